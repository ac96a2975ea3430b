"""Checkpoints: safetensors weights + a JSON sidecar. Loading never executes code from the file.

`NAME.safetensors` holds tensors only (model weights, optimizer moments); `NAME.json` beside it
holds everything else (model config, skeleton, class names, canonical mode, held-out subject,
training info, code version, optimizer hyper-parameters). A copy of the JSON is also stored in the
safetensors header metadata, so a lone .safetensors file still loads. Writes are atomic.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imm_model.errors import CheckpointError

if TYPE_CHECKING:
    import torch

FORMAT = "imm-checkpoint-1"


def sidecar_path(path: Path | str) -> Path:
    return Path(path).with_suffix(".json")


def _atomic_write(path: Path, write) -> None:
    tmp = path.with_name(path.name + ".tmp")
    write(tmp)
    os.replace(tmp, path)


def save_checkpoint(path: Path | str, tensors: dict[str, torch.Tensor], meta: dict[str, Any]) -> None:
    """Write `path` (.safetensors) and its JSON sidecar atomically."""
    from safetensors.torch import save_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"format": FORMAT, **meta}
    text = json.dumps(meta, indent=1, sort_keys=True)
    tensors = {k: v.detach().contiguous().clone() for k, v in tensors.items()}
    _atomic_write(path, lambda tmp: save_file(tensors, str(tmp), metadata={"imm": json.dumps(meta, sort_keys=True)}))
    _atomic_write(sidecar_path(path), lambda tmp: tmp.write_text(text + "\n"))
    os.chmod(path, 0o644)


def load_checkpoint(path: Path | str, framework: str = "pt") -> tuple[dict[str, Any], dict[str, Any]]:
    """-> (tensors, meta): torch tensors, or numpy arrays with framework="np" (torch is not imported then). Any
    problem -> CheckpointError with a one-line message."""
    from safetensors import safe_open

    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: checkpoint not found")
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
    try:
        text = side.read_text() if side.is_file() else header.get("imm")
        if text is None:
            raise CheckpointError(f"{path}: no JSON sidecar ({side.name}) and no embedded metadata")
        meta = json.loads(text)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:  # RecursionError: absurdly nested JSON
        raise CheckpointError(f"{side}: unreadable checkpoint sidecar ({type(err).__name__})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CheckpointError(f"{side}: not an IMM checkpoint sidecar (format {meta.get('format') if isinstance(meta, dict) else '?'})")
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
    """Copy a run's checkpoint as a generator-only checkpoint (what inference needs)."""
    tensors, meta = load_checkpoint(best)
    generator = {k: v for k, v in tensors.items() if k.startswith("generator.")}
    save_checkpoint(out, generator, {k: v for k, v in meta.items() if k != "format"} | {"kind": "generator"})
