"""The view in the URL's query string, so a link reopens what its sender saw:
`?seq=s01s02/03/001&mix=kicking:1,hugging:0.5&scale=1&frame=12&layout=overlay&camera=front&map=tsne` (a class by
part: `mix=upper:shaking_hands:1,lower:pushing:-1`, the label keys of imm_model/data/labels.py), `&raw=1`
when the clean-up is off, `&model=diffusion` when another model than the studio's first draws, `&seed=12` for a
seeded model, `&spread=0.3` for one with a spread setting, `&compare=diffusion,retrieval` for other models'
followers drawn beside the current one's and `&plot=distance:A.right_hand:B.right_hand` (or `speed:B.head`) for the
quantity the chart under the view plots instead of its error and contact (explorer/session/joint_plot.py).

Everything read from a URL is validated here (it comes from whoever wrote the link): unknown keys are ignored,
bad values are named in one line and left out, the rest still applies.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol
from urllib.parse import parse_qs, quote, urlencode

from explorer.session.joint_plot import JointPlot
from explorer.session.side_by_side import MAX_COMPARED
from explorer.session.words import one_line
from explorer.ui.chart_panel import pick_state, picked_plot
from imm_model.data.labels import Label
from imm_model.errors import LabelError, quoted

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.session.session import Session


MAX_QUERY = 2000  # characters; a longer query is refused as a whole
LAYOUTS = ("overlay", "side_by_side")
MAPS = ("tsne", "umap")
MAX_SEED = 2**31 - 5  # room for the side-by-side variations after it (explorer/session/session.py MAX_VARIATIONS)


def view_query(view: dict) -> str:
    """{seq, label (a Label: its values unscaled), scale, frame, layout, camera, map, raw, model, seed, spread, compare,
    plot} -> "?..." (None values are left out)."""
    parts = {}
    if view.get("seq"):
        parts["seq"] = view["seq"]
    mix = view["label"].text(value_sep=":") if view.get("label") is not None else ""
    parts["mix"] = mix or "none"
    for key in ("scale", "frame", "layout", "camera", "map", "raw", "model", "seed", "spread", "compare", "plot"):
        if view.get(key) is not None:
            parts[key] = f"{view[key]:g}" if isinstance(view[key], float) else str(view[key])
    return "?" + urlencode(parts, safe=":,/", quote_via=quote)


def _hand_camera(text: str, cameras) -> str:
    """A hand-placed camera ("hand:" and nine numbers: explorer/rendering/camera.py hand_placement), checked."""
    from explorer.rendering.camera import HAND, hand_placement

    if not text.startswith(HAND + ":"):
        _fail(f"camera {quoted(text)} is not one of {', '.join(cameras)} nor {HAND}:...")
    try:
        hand_placement(text)
    except ValueError as err:
        _fail(f"camera {quoted(text)}: {err}")
    return text


def _number(text: str, lo: float, hi: float, what: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise ValueError(f"{what} {quoted(text)} is not a number") from None
    if not math.isfinite(x) or not lo <= x <= hi:
        raise ValueError(f"{what} {quoted(text)} is outside {lo:g}..{hi:g}")
    return x


def _mix(text: str, class_names) -> Label:
    """"kicking:1,upper:hugging:0.5" -> the Label (a class alone is the whole body), each weight a slider's, -1..1."""
    if text == "none":
        return Label.neutral(class_names)
    try:
        label = Label.parse(text, class_names, value_sep=":")
    except LabelError as err:
        raise ValueError(f"mix: {one_line(err)}") from None
    for key, w in label.keys().items():
        if not -1.0 <= w <= 1.0:
            raise ValueError(f"mix weight of {key} {w:g} is outside -1..1")
    return label


def parse_view(query: str, class_names, sequence_ids, cameras, models=(), joints=()) -> tuple[dict, list[str]]:
    """"?seq=...&mix=..." -> (the valid parts, one-line reasons for the others)."""
    query = query.lstrip("?")
    if len(query) > MAX_QUERY:
        return {}, [f"the link's view is {len(query)} characters long (at most {MAX_QUERY}): ignored"]
    fields = {k: v[-1] for k, v in parse_qs(query, keep_blank_values=True).items()}
    parsers = {
        "seq": lambda v: v if v in sequence_ids else _fail(f"no sequence {quoted(v)} in this dataset"),
        "mix": lambda v: _mix(v, class_names),
        "scale": lambda v: _number(v, 0.0, 2.0, "scale"),
        "frame": lambda v: int(_number(v, 0, 1e6, "frame")),
        "layout": lambda v: v if v in LAYOUTS else _fail(f"layout {quoted(v)} is not one of {', '.join(LAYOUTS)}"),
        "camera": lambda v: v if v in cameras else _hand_camera(v, cameras),
        "map": lambda v: v if v in MAPS else _fail(f"map {quoted(v)} is not one of {', '.join(MAPS)}"),
        "raw": lambda v: {"1": True, "0": False}[v] if v in ("0", "1") else _fail(f"raw {quoted(v)} is not 0 or 1"),
        "model": lambda v: v if v in models else _fail(f"model {quoted(v)} is not one of {', '.join(models) or 'this studio'}"),
        "seed": _seed,
        "spread": lambda v: _number(v, 0.0, 1.0, "spread"),
        "compare": lambda v: _compared(v, models),
        "plot": lambda v: JointPlot.parse(v, joints),
    }
    view, problems = {}, []
    for key, parse in parsers.items():
        if key in fields:
            try:
                view[key] = parse(fields[key])
            except ValueError as err:
                problems.append(str(err))
    return view, problems


def _seed(text: str) -> int:
    if not (text.isascii() and text.isdigit()):
        raise ValueError(f"seed {text[:20]!r} is not a whole number")
    if int(text) > MAX_SEED:
        raise ValueError(f"seed {text[:20]!r} is outside 0..{MAX_SEED}")
    return int(text)


def _compared(text: str, models) -> list[str]:
    names = list(dict.fromkeys(n for n in text.split(",") if n))
    unknown = [n for n in names if n not in models]
    if unknown:
        raise ValueError(f"compare: model {unknown[0][:40]!r} is not one of {', '.join(models) or 'this studio'}")
    if len(names) > MAX_COMPARED:
        raise ValueError(f"compare: at most {MAX_COMPARED} models, not {len(names)}")
    return names


def _fail(message: str):
    raise ValueError(message)


class ViewHolder(Protocol):
    """What a link's view is read from and applied to (the Studio is one)."""

    state: Any
    session: Session
    scene: Scene

    def load_sequence(self, index: int) -> None: ...

    def set_label(self, weights: Sequence[float], scale: float = 1.0) -> None: ...

    def set_camera(self, preset: str) -> None: ...


def current_view(studio: ViewHolder) -> dict:
    """What the studio shows now, as view_query takes it (an uploaded leader has no sequence id to link to)."""
    ses, s = studio.session, studio.state
    return {
        "seq": None if ses.upload else ses.data.sequence_ids[ses.index],
        "label": ses.label,
        "scale": round(float(ses.scale), 3),
        "frame": None if s.playing else int(s.frame or 0),
        "layout": s.scene_layout,
        "camera": studio.scene.camera.placement(),
        "map": s.projection,
        "raw": None if ses.cleaned_up else 1,  # left out of the link while the clean-up is on, as by default
        "model": None if ses.model is ses.map_model else ses.model_name,  # left out for the model the studio opens with
        "seed": ses.seed if ses.seeded else None,
        "spread": None if ses.spread is None else round(float(ses.spread), 3),
        "compare": ",".join(ses.side_by_side.compared_names) or None,
        "plot": plot.text() if (plot := picked_plot(s, ses.data.skeleton.joint_names)) else None,  # None: the default chart
    }


def apply_view(studio: ViewHolder, query: str) -> None:
    """Open the view a link describes; what cannot be applied is named in the page's alert."""
    from explorer.rendering.camera import CAMERA_PRESETS

    ses, s = studio.session, studio.state
    view, problems = parse_view(query, ses.class_names, set(ses.data.sequence_ids), CAMERA_PRESETS, tuple(ses.models),
                                ses.data.skeleton.joint_names)
    with s:  # the model and seed first: the sequence and the mix are then drawn by them once
        if "model" in view:
            s.model_name = view["model"]
        if "seed" in view:
            s.seed = view["seed"]
        if "compare" in view:
            s.compare_models = view["compare"]
    if "spread" in view:
        if ses.spread is None:
            problems.append(f"spread: {ses.model_title()} has no spread setting")
        else:
            with s:
                s.spread = view["spread"]  # applied with the mix below (app.py's mix handler)
    if "seq" in view:
        studio.load_sequence(ses.data.index_of(view["seq"]))
    if "mix" in view:  # as every model the link draws with reads it (one without part labels refuses a part mix: left out)
        try:
            ses.check_label(view["mix"])
        except LabelError as err:
            problems.append(f"mix: {one_line(err)}")
            del view["mix"]
    if "mix" in view or "scale" in view:
        studio.set_label(view["mix"].mix if "mix" in view else ses.label.mix, view.get("scale", 1.0))
    with s:
        if "frame" in view:
            s.frame = min(view["frame"], ses.num_frames - 1)
        if "layout" in view:
            s.scene_layout = view["layout"]
        if "map" in view:
            s.projection = view["map"]
        if "raw" in view:
            s.clean_up = not view["raw"]
        if "plot" in view:
            s.update(pick_state(view["plot"]))
        if problems:
            s.error = "link: " + "; ".join(problems)
    if "camera" in view:
        studio.set_camera(view["camera"])
