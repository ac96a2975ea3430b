"""Checkpoints: safetensors weights + a JSON sidecar. Loading never executes code from the file.

`NAME.safetensors` holds tensors only (model weights, optimizer moments); `NAME.json` beside it
holds everything else (model config, skeleton, class names, canonical mode, held-out subject,
training info, code version, optimizer hyper-parameters, the weights' digest). A copy of the JSON is also stored in
the safetensors header metadata, so a lone .safetensors file still loads. Writes are atomic, and a sidecar is only
accepted beside the weights it was saved with.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from imm_model.errors import CheckpointError, IMMError
from imm_model.inputs import MAX_SETTINGS_BYTES, check_input, read_input_text

if TYPE_CHECKING:
    import torch

FORMAT = "imm-checkpoint-1"
DIGEST = "weights_sha256"  # in the sidecar and the header copy: which weights the metadata was saved with


def sidecar_path(path: Path | str) -> Path:
    return Path(path).with_suffix(".json")


def _raw_bytes(tensor) -> np.ndarray:
    """A tensor's (or array's) bytes as a flat uint8 array, the same for torch and numpy loads of one file."""
    if isinstance(tensor, np.ndarray):
        return np.ascontiguousarray(tensor).reshape(-1).view(np.uint8)
    import torch

    return tensor.detach().cpu().contiguous().reshape(-1).view(torch.uint8).numpy()


def weights_digest(tensors: dict[str, Any]) -> str:
    """SHA-256 of the tensors' names, shapes and bytes (not of the file, whose header holds the digest itself)."""
    h = hashlib.sha256()
    for name in sorted(tensors):
        data = _raw_bytes(tensors[name])
        h.update(f"{name}:{tuple(tensors[name].shape)}:{data.size}\n".encode())
        h.update(data)
    return h.hexdigest()


def save_checkpoint(path: Path | str, tensors: dict[str, torch.Tensor], meta: dict[str, Any], replace: bool = True) -> None:
    """Write `path` (.safetensors) and its JSON sidecar, both carrying the weights' digest. Both are written to
    temporary files first and then renamed into place; a kill between the two renames leaves a pair whose digests
    differ, which `load_checkpoint` refuses. A full disk is a one-line error and leaves the old pair. Without
    `replace`, a pair that exists (either file) is refused and left as it was."""
    from safetensors.torch import save

    from imm_model.outputs import write_files

    path = Path(path)
    tensors = {k: v.detach().cpu().contiguous().clone() for k, v in tensors.items()}
    meta = {"format": FORMAT, **meta, DIGEST: weights_digest(tensors)}
    blob = save(tensors, metadata={"imm": json.dumps(meta, sort_keys=True)})
    try:
        write_files([(path, blob), (sidecar_path(path), json.dumps(meta, indent=1, sort_keys=True) + "\n")], replace)
    except IMMError as err:
        raise CheckpointError(str(err)) from None


def _check_pair(path: Path, side: Path, meta: dict, embedded: dict | None, tensors: dict) -> None:
    """The sidecar must describe these weights: its digest equal to theirs; a sidecar without a digest beside weights
    with one is from another save. Checkpoints saved before digests (neither has one) are matched by their training
    record (epoch, best epoch) against the header's copy. Otherwise the sidecar may differ from the header's copy:
    it is the editable description of the weights, the copy a fallback for a lone .safetensors file."""
    actual = weights_digest(tensors)
    header_ok = isinstance(embedded, dict) and embedded.get(DIGEST) == actual
    advice = f"; {path.name} is whole: delete {side.name} to load it with the metadata saved inside it" if header_ok else ""
    if DIGEST in meta:
        if meta[DIGEST] != actual:
            raise CheckpointError(f"{path}: the weights and {side.name} come from different saves (weights digest "
                                  f"differs: an interrupted save?){advice}")
    elif isinstance(embedded, dict) and DIGEST in embedded:
        raise CheckpointError(f"{path}: {side.name} was not saved with these weights (it has no weights digest){advice}")
    elif isinstance(embedded, dict) and "training" in embedded and "training" in meta:
        if json.dumps(embedded["training"], sort_keys=True) != json.dumps(meta["training"], sort_keys=True):
            raise CheckpointError(f"{path}: the weights and {side.name} come from different saves (their training "
                                  f"records differ: an interrupted save?)")


def peek_sidecar(path: Path | str) -> dict:
    """A checkpoint's JSON sidecar, read within MAX_SETTINGS_BYTES and before its weights are (to choose whether to
    load them); {} when it is absent, unreadable or not a JSON object."""
    try:
        meta = json.loads(read_input_text(sidecar_path(path), "checkpoint sidecar", MAX_SETTINGS_BYTES))
    except (OSError, ValueError, RecursionError, IMMError):
        return {}
    return meta if isinstance(meta, dict) else {}


def _parse_meta(text: str, where: Path) -> dict:
    try:
        meta = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:  # RecursionError: absurdly nested JSON
        raise CheckpointError(f"{where}: unreadable checkpoint sidecar ({type(err).__name__})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CheckpointError(f"{where}: not an IMM checkpoint sidecar (format {meta.get('format') if isinstance(meta, dict) else '?'})")
    return meta


def load_checkpoint(path: Path | str, framework: str = "pt") -> tuple[dict[str, Any], dict[str, Any]]:
    """-> (tensors, meta): torch tensors, or numpy arrays with framework="np" (torch is not imported then). The
    sidecar is checked against the weights (`_check_pair`). Any problem -> CheckpointError with a one-line message."""
    from safetensors import safe_open

    path = Path(path)
    check_input(path, "checkpoint", error=CheckpointError)
    try:
        tensors = {}
        with safe_open(str(path), framework=framework) as f:
            header = f.metadata() or {}
            for k in f.keys():
                tensors[k] = f.get_tensor(k)
    except Exception as err:  # safetensors raises several types for corrupt files
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise CheckpointError(f"{path}: not a readable safetensors checkpoint ({reason})") from None
    side = sidecar_path(path)
    embedded = None
    if header.get("imm") is not None:
        try:
            embedded = json.loads(header["imm"])
        except (json.JSONDecodeError, RecursionError):
            embedded = None  # judged below only if there is no sidecar to use instead
    if side.is_file():
        try:
            text = side.read_text()
        except (OSError, UnicodeDecodeError) as err:
            raise CheckpointError(f"{side}: unreadable checkpoint sidecar ({type(err).__name__})") from None
        meta = _parse_meta(text, side)
        _check_pair(path, side, meta, embedded, tensors)
        return tensors, meta
    if header.get("imm") is None:
        raise CheckpointError(f"{path}: no JSON sidecar ({side.name}) and no embedded metadata")
    meta = _parse_meta(header["imm"], path)
    if DIGEST in meta and meta[DIGEST] != weights_digest(tensors):
        raise CheckpointError(f"{path}: the weights do not match the digest saved with them (a damaged file?)")
    return tensors, meta


def prefixed(tensors: dict[str, torch.Tensor], prefix: str) -> dict[str, torch.Tensor]:
    """The tensors under `prefix.` with the prefix removed."""
    n = len(prefix) + 1
    return {k[n:]: v for k, v in tensors.items() if k.startswith(prefix + ".")}


def check_state(state: dict[str, Any], expected: dict[str, tuple[int, ...]], what: str, path: Path | str) -> None:
    """Weights (tensors or arrays) against the names and shapes a model expects: a one-line CheckpointError naming
    the first missing, unexpected or mismatched key."""
    missing = [k for k in expected if k not in state]
    unexpected = [k for k in state if k not in expected]
    if missing:
        raise CheckpointError(f"{path}: {what} weights missing key {missing[0]!r} ({len(missing)} missing): different architecture?")
    if unexpected:
        raise CheckpointError(f"{path}: unexpected {what} key {unexpected[0]!r}: different architecture?")
    for k, shape in expected.items():
        if tuple(state[k].shape) != tuple(shape):
            raise CheckpointError(f"{path}: {what} key {k!r} has shape {tuple(state[k].shape)}, model expects {tuple(shape)}")


def load_module_state(module: torch.nn.Module, state: dict[str, torch.Tensor], what: str, path: Path | str) -> None:
    """Strict load with a one-line CheckpointError naming the first missing/unexpected/mismatched key."""
    check_state(state, {k: tuple(v.shape) for k, v in module.state_dict().items()}, what, path)
    module.load_state_dict(state)


# ---- optimizer state as tensors + JSON ---------------------------------------------------------
def optimizer_to_tensors(opt: torch.optim.Optimizer, prefix: str) -> tuple[dict[str, torch.Tensor], dict]:
    import torch

    sd = opt.state_dict()
    tensors, scalars = {}, {}
    for pid, st in sd["state"].items():
        for name, v in st.items():
            if torch.is_tensor(v):
                tensors[f"{prefix}.{pid}.{name}"] = v.detach().cpu()
            else:
                scalars[f"{pid}.{name}"] = v
    return tensors, {"param_groups": sd["param_groups"], "scalars": scalars}


def optimizer_from_tensors(opt: torch.optim.Optimizer, tensors: dict[str, torch.Tensor], meta: dict, prefix: str) -> None:
    state: dict[int, dict] = {}
    for k, v in prefixed(tensors, prefix).items():
        pid, name = k.split(".", 1)
        state.setdefault(int(pid), {})[name] = v
    for k, v in meta["scalars"].items():
        pid, name = k.split(".", 1)
        state.setdefault(int(pid), {})[name] = v
    opt.load_state_dict({"state": state, "param_groups": meta["param_groups"]})


def final_checkpoint(fold_dir: Path | str) -> Path:
    """The model a training run's fold ships: final.safetensors (a refit) if present, else best.safetensors."""
    fold_dir = Path(fold_dir)
    final = fold_dir / "final.safetensors"
    return final if final.exists() else fold_dir / "best.safetensors"


def export_generator(best: Path | str, out: Path | str) -> None:
    """Copy a run's checkpoint as a generator-only checkpoint (what inference needs: the GAN's generator, or the
    diffusion model's denoiser)."""
    tensors, meta = load_checkpoint(best)
    generator = {k: v for k, v in tensors.items() if k.startswith(("generator.", "denoiser."))}
    save_checkpoint(out, generator, {k: v for k, v in meta.items() if k != "format"} | {"kind": "generator"})
