"""The model families and the one registry that maps a checkpoint or a recipe to its family.

A family is one folder here (its config, networks, sampler, trainer, recipes and `ReactionModel` subclass) and one
entry in FAMILIES; nothing outside this module asks which family a model or a recipe belongs to. To add one: a folder
with an `__init__.py` defining `FAMILY = Family(...)` (base.py says what each field is), and its line below.
"""

from __future__ import annotations

import json
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from imm_model.errors import CheckpointError, IMMError
from imm_model.families import diffusion, gan, retrieval
from imm_model.families.base import Family, ReactionModel
from imm_model.families.output_check import check_model_outputs
from imm_model.inputs import MAX_SETTINGS_BYTES, read_input_text

FAMILIES: dict[str, Family] = {f.name: f for f in (gan.FAMILY, diffusion.FAMILY, retrieval.FAMILY)}
LEGACY_FAMILY = "gan"  # checkpoints saved before sidecars named their family hold the paper's GAN


def load_model(path: Path | str | None = None, device: str = "cpu", data: Path | str | None = None) -> ReactionModel:
    """Load a checkpoint of any family (default: the bundled default model, paths.SAMPLE_DEFAULT, the diffusion model)
    as that family's ReactionModel; any problem is one CheckpointError line naming the file. `data`: the dataset bundle
    the user names, for a model that reads its training data at load (retrieval); others ignore it."""
    from imm_model.checkpoint import load_checkpoint
    from imm_model.paths import SAMPLE_DEFAULT

    path = Path(path) if path is not None else SAMPLE_DEFAULT
    arrays, meta = load_checkpoint(path, framework="np")
    if meta.get("kind") == "classifier":
        raise CheckpointError(f"{path}: a reaction classifier (a 'reads as' judge), not a reaction model")
    name = meta.get("family", LEGACY_FAMILY)
    if name not in FAMILIES:
        raise CheckpointError(f"{path}: sidecar family {str(name)[:40]!r} is none of {', '.join(FAMILIES)}")
    model = FAMILIES[name].model_class().from_checkpoint(arrays, meta, path, device, None if data is None else Path(data))
    return check_model_outputs(model)


def attach_draft(model: ReactionModel, candidates) -> None:
    """Give `model` as its draft (ReactionModel.attach_draft) the first of `candidates` (checkpoint paths) distilled from
    it; one missing, unreadable or distilled from another model is passed over, its weights never loaded."""
    from imm_model.checkpoint import DIGEST, peek_sidecar

    for path in map(Path, candidates):
        try:
            teacher = peek_sidecar(path).get("teacher")
            if not isinstance(teacher, dict) or teacher.get(DIGEST) != model.info.get(DIGEST):
                continue
            model.attach_draft(load_model(path))
            return
        except (OSError, ValueError, AttributeError, IMMError):
            continue


def recipe_names() -> list[str]:
    """Every named recipe of every family."""
    return [name for family in FAMILIES.values() for name in family.recipes()]


def family_of(config) -> Family:
    """The family whose recipes a config (a recipe's typed config) belongs to."""
    for family in FAMILIES.values():
        if any(type(config) is type(recipe) for recipe in family.recipes().values()):
            return family
    raise TypeError(f"{type(config).__name__} is no family's recipe config")


def load_recipe(name_or_path: str, **overrides: Any) -> tuple[Family, Any]:
    """A named recipe, or a JSON file of overrides on one ({"base": "imm-diffusion", "steps": 3000}; without a base,
    {"family": NAME} picks that family's default recipe, else the GAN's `imm`) -> (its family, its config). Fields
    holding objects (model sizes, sampler guidance) merge key by key. `overrides` set fields (None: keep the
    recipe's); a field the family's recipes lack is a one-line ValueError."""
    for family in FAMILIES.values():
        if name_or_path in family.recipes():
            return family, _overridden(family, family.recipes()[name_or_path], overrides)
    path = Path(name_or_path)
    if not path.exists():
        raise ValueError(f"unknown config {name_or_path!r}: not one of {', '.join(recipe_names())} nor a JSON file")
    d = _read_recipe(path)
    base_name = d.pop("base", None)
    if base_name is None:
        family_name = d.get("family", LEGACY_FAMILY)
        if family_name not in FAMILIES:
            raise ValueError(f"{path}: family must be one of {', '.join(FAMILIES)}, not {str(family_name)[:40]!r}")
        base_name = FAMILIES[family_name].default_recipe
    family = next((f for f in FAMILIES.values() if isinstance(base_name, str) and base_name in f.recipes()), None)
    if family is None:
        raise ValueError(f"{path}: unknown base config {str(base_name)[:40]!r} (one of {', '.join(recipe_names())})")
    base = family.recipes()[base_name].to_dict()
    for key, value in base.items():
        if isinstance(value, dict):
            if not isinstance(d.get(key, {}), dict):
                raise ValueError(f"{path}: {key} must be a JSON object, not {str(d[key])[:40]!r}")
            d[key] = value | d.get(key, {})
    merged = base | d
    merged.setdefault("name", path.stem)
    return family, _overridden(family, type(family.recipes()[base_name]).from_dict(merged), overrides)


def _overridden(family: Family, config, overrides: dict[str, Any]):
    given = {k: v for k, v in overrides.items() if v is not None}
    names = {f.name for f in fields(config)}
    for key in given:
        if key not in names:
            raise ValueError(f"{key} does not apply to {family.title}'s recipe {config.name!r}")
    return replace(config, **given)


def _read_recipe(path: Path) -> dict:
    try:
        d = json.loads(read_input_text(path, "config", MAX_SETTINGS_BYTES))  # a regular file, within the bound
    except (json.JSONDecodeError, RecursionError) as err:
        where = f"{err.msg} at line {err.lineno}" if isinstance(err, json.JSONDecodeError) else "nested too deeply"
        raise ValueError(f"{path}: invalid JSON ({where})") from None
    if not isinstance(d, dict):
        raise ValueError(f"{path}: a config is a JSON object ({{\"base\": \"imm\", ...overrides}}), not {type(d).__name__}")
    return d


def same_recipe(config, saved: Any) -> bool:
    """Whether a run saved with config dict `saved` continues under `config`: more of the length option (epochs,
    steps) is fine, and so is whatever the family's own rule allows (options retired at their off values)."""
    family = family_of(config)
    current = config.to_dict()
    if family.same_recipe is not None:
        return family.same_recipe(saved, current)
    length = family.length_option
    strip = lambda d: {k: v for k, v in d.items() if k != length}  # noqa: E731
    return isinstance(saved, dict) and strip(saved) == strip(current)
