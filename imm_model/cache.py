"""The cache: per-fold reaction classifiers (evaluation judges, training critics), trained once, and the keys and
place of every cached entry (evaluation/baselines.py caches the trained baseline models here too).

Entries are keyed by what determines them (dataset hash, held-out subject, config, code version), so a
changed dataset or recipe never reuses a stale entry. Files are safetensors + JSON (imm_model.checkpoint):
loading never runs code. An unreadable or mismatched entry is reported on stderr and rebuilt, never used.
Location: $IMM_CACHE_DIR, else ~/.cache/imm-studio.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

import imm_model
from imm_model.checkpoint import load_checkpoint, load_module_state, save_checkpoint
from imm_model.data.dataset import InteractionDataset, dataset_hash
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError, IMMError
from imm_model.model.classifier import VERSION as CLASSIFIER_VERSION
from imm_model.model.classifier import MotionClassifier, motion_inputs, train_classifier
from imm_model.model.classifier_config import ClassifierConfig


def cache_dir() -> Path:
    """The cache folder; one that cannot be a folder (it, or a folder above it, is a file) is a one-line IMMError
    here, before anything is trained for it, not when the first entry is saved."""
    env = os.environ.get("IMM_CACHE_DIR")
    path = Path(env) if env else Path.home() / ".cache" / "imm-studio"
    existing = next(p for p in (path, *path.absolute().parents) if p.exists())  # the root always exists
    if not existing.is_dir():
        raise IMMError(f"{'IMM_CACHE_DIR' if env else 'the cache folder'} {path}: {existing} is not a folder; "
                       f"set IMM_CACHE_DIR to a folder")
    return path


def entry_key(kind: str, data: InteractionDataset, subject: str, config: dict) -> str:
    text = json.dumps({"kind": kind, "data": dataset_hash(data), "subject": subject, "config": config,
                       "code": imm_model.__version__}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def note(message: str) -> None:
    """A line about the cache on stderr (what was trained or rebuilt)."""
    print(message, file=sys.stderr, flush=True)


def fold_classifier(cfg: ClassifierConfig, data: InteractionDataset, subject: str | None, progress: bool = True) -> MotionClassifier:
    """The classifier `cfg` trained on the real motion of fold `subject`'s training subjects (None: every sequence), cached."""
    key = entry_key("classifier", data, subject, cfg.to_dict() | {"version": CLASSIFIER_VERSION})
    path = cache_dir() / "classifiers" / f"{subject or 'all'}-{cfg.inputs}-{cfg.arch}-{key}.safetensors"
    model = MotionClassifier(cfg, 3 * data.skeleton.num_joints * (2 if cfg.inputs == "interaction" else 1), len(data.class_names))
    if path.exists():
        try:
            tensors, meta = load_checkpoint(path)
            if meta.get("key") != key:
                raise CheckpointError(f"{path}: cache key mismatch")
            load_module_state(model, tensors, "classifier", path)
            return model.eval()
        except CheckpointError as err:
            note(f"cache: {err}; rebuilding")
    train = loso_fold(data.subject_pairs, subject).train if subject else np.arange(len(data))
    leaders, followers = zip(*(data.canonical(int(i)) for i in train), strict=True)
    t0 = time.perf_counter()
    model = train_classifier(cfg, motion_inputs(list(leaders), list(followers), cfg.inputs), data.actions[train],
                             len(data.class_names), progress, desc=f"{cfg.inputs} {cfg.arch} classifier, fold {subject or 'none'}")
    note(f"cache: trained the {cfg.inputs}-only {cfg.arch} classifier for fold {subject or 'none'} in {time.perf_counter() - t0:.0f} s"
         .replace("interaction-only", "interaction"))
    save_checkpoint(path, model.state_dict(), {"kind": "classifier", "key": key, "subject": subject, "config": cfg.to_dict(),
                                               "class_names": list(data.class_names)})
    return model
