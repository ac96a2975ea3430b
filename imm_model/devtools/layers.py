"""The structure check: imports only go down the layers, and no modules import each other in a circle.

    python -m imm_model.devtools.layers      # one line per problem, rc 1; a summary line and rc 0 when there is none

Every Import and ImportFrom node of every module of imm_model/ and explorer/ counts, at module level or inside a
function alike (a lazy import is a dependency all the same). A module may import modules of its own layer and of the
layers below it. Each top-level module and package of imm_model and of explorer is placed in a layer in LAYERS below,
so a new one fails the check until it is given a place. Imports spelled as strings (importlib, entry points) are not seen; the
`imm` command finds its subcommand modules that way on purpose, from the top.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

# Lowest first. A unit is a top-level module or package of imm_model (its submodules with it), or the studio.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    # what every layer uses: errors, paths, typed configs, checkpoint files, checked inputs, atomic outputs, the device choice
    ("foundation", ("imm_model", "imm_model.errors", "imm_model.paths", "imm_model.typed_config", "imm_model.device",
                    "imm_model.checkpoint", "imm_model.outputs", "imm_model.inputs")),
    # skeletons, datasets and their readers, splits, and the geometry of poses
    ("data", ("imm_model.skeleton", "imm_model.data", "imm_model.contact", "imm_model.cleanup",
              "imm_model.interaction_file")),
    # the networks every family shares (the reaction classifiers), the cached per-fold classifiers, the studio's judge
    ("model", ("imm_model.model", "imm_model.cache", "imm_model.reads_as")),
    # what every family's training shares: batches, augmentation, geometric terms, part composites, curves
    ("training", ("imm_model.training",)),
    # the model families (each a folder: config, networks, sampler, trainer, recipes, model class), their registry,
    # and the inference API over them
    ("families", ("imm_model.families", "imm_model.inference")),
    ("evaluation", ("imm_model.evaluation",)),
    # the commands and tools built on the library
    ("applications", ("imm_model.reproduce", "imm_model.generate", "imm_model.train", "imm_model.cli", "imm_model.devtools")),
    # the studio (a separate package), bottom to top: its one adapter to trame's internals, its picture-making, the
    # user's session, the serving processes, the page, and the front ends that start it
    ("studio adapter", ("explorer", "explorer.trame_adapter")),
    ("studio rendering", ("explorer.rendering",)),
    ("studio session", ("explorer.session",)),
    ("studio serving", ("explorer.serving",)),
    ("studio ui", ("explorer.ui",)),
    ("studio front ends", ("explorer.commands", "explorer.desktop")),
)
# A package's __main__ is an entry point (`python -m package`): it sits in this layer whatever its package.
ENTRY_POINT_LAYER = "applications"
# Imports that go up, or close a circle, on purpose, each with its reason.
ALLOWED_UPWARD: dict[tuple[str, str], str] = {
    ("imm_model", "imm_model.inference"):
        "the package's lazy re-export of the inference API (imm_model.synthesize), run on attribute access only",
    ("imm_model.families.base", "imm_model.families"):
        "ReactionModel.load() asks the registry for the checkpoint's family; the registry imports each family, whose "
        "model class is built on the base",
    ("explorer.serving.worker", "explorer.ui.app"): "a studio process builds the page it serves",
    ("explorer.serving.zygote", "explorer.ui.app"): "the page is imported once before forking, so no tab imports it again",
}
ROOTS = ("imm_model", "explorer")


@dataclass(frozen=True)
class Import:
    source: str  # the importing module
    target: str  # the imported module (a package's __init__ is the package)
    line: int


def repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def module_files(root: Path) -> dict[str, Path]:
    """{module name: file} for every .py file under the ROOTS packages of `root`."""
    out = {}
    for top in ROOTS:
        for path in sorted((root / top).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


def _resolve(name: str, known: Iterable[str]) -> str | None:
    """The longest known module that `name` is or lies in (None: outside the project)."""
    known = set(known)
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        candidate = ".".join(parts[:k])
        if candidate in known:
            return candidate
    return None


def imports(modules: dict[str, Path]) -> list[Import]:
    """Every import between project modules, wherever it is written in the module."""
    out = []
    for source, path in modules.items():
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: from the importing module's package
                    package = source.split(".")[: len(source.split(".")) - node.level + (1 if is_package else 0)]
                    base = ".".join([*package, base] if base else package)
                targets = [f"{base}.{alias.name}" for alias in node.names]  # a submodule, or a name in `base`
            else:
                continue
            for target in targets:
                resolved = _resolve(target, modules)
                if resolved is not None and resolved != source:
                    out.append(Import(source, resolved, node.lineno))
    return out


def layer_of(module: str) -> str | None:
    """The layer a module belongs to (None: its unit is in no layer)."""
    if module.rsplit(".", 1)[-1] == "__main__" and not module.startswith("explorer"):
        return ENTRY_POINT_LAYER
    # a package root is the unit of its own __init__ only: each of its top-level modules needs a place of its own
    units = [u for _, us in LAYERS for u in us if u not in ROOTS or module == u]
    unit = _resolve(module, units)
    return next((layer for layer, units in LAYERS if unit in units), None)


def cycles(edges: Iterable[tuple[str, str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each as a sorted list."""
    graph: dict[str, set[str]] = {}
    for a, b in edges:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:  # depth is bounded by the number of modules (a few hundred)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def problems(root: Path | None = None) -> tuple[list[str], int, int]:
    """-> (one line per problem, modules checked, imports checked)."""
    root = root or repo_root()
    modules = module_files(root)
    found = imports(modules)
    rank = {layer: k for k, (layer, _) in enumerate(LAYERS)}
    out = []
    for module in sorted(modules):
        if layer_of(module) is None:
            out.append(f"{module}: in no layer (place it in imm_model/devtools/layers.py LAYERS)")
    kept = []
    for imp in found:
        if (imp.source, imp.target) in ALLOWED_UPWARD:
            continue
        kept.append(imp)
        src, dst = layer_of(imp.source), layer_of(imp.target)
        if src is not None and dst is not None and rank[dst] > rank[src]:
            path = modules[imp.source].relative_to(root)
            out.append(f"{path}:{imp.line}: {imp.source} ({src}) imports {imp.target} ({dst}), a layer above it")
    for component in cycles((i.source, i.target) for i in kept):
        out.append(f"import cycle: {' <-> '.join(component)}")
    return out, len(modules), len(found)


def main(argv: list[str] | None = None) -> int:
    found, n_modules, n_imports = problems()
    for line in found:
        print(line)
    if found:
        return 1
    order = " -> ".join(layer for layer, _ in LAYERS)
    print(f"layers: {n_modules} modules, {n_imports} imports, all going down ({order}), no import cycle")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
