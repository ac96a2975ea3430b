"""Keyboard shortcuts: playback, frames, the label sliders and a help card.

The page listens for keydown on the document (not while the user types in a field or has a slider focused,
whose own arrow keys move it) and sends the key; the studio acts on it here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from explorer.session.loop_range import with_end

if TYPE_CHECKING:
    from explorer.session.session import Session


SLIDER_STEP = 0.1

KEY_HELP = (
    ("space", "play / pause"),
    ("← →", "previous / next frame"),
    ("Home End", "first / last frame"),
    ("[ ]", "loop range: in / out at this frame"),
    ("M", "match: the sequence's own class at +1"),
    ("R", "reset every slider to 0"),
    ("1 … 6", "select a class slider"),
    ("↑ ↓", f"move the selected slider by {SLIDER_STEP}"),
    ("?", "show or hide these keys"),
)
KEYS = (" ", "ArrowLeft", "ArrowRight", "Home", "End", "[", "]", "m", "M", "r", "R", "ArrowUp", "ArrowDown", "?", *map(str, range(1, 10)))

# One JS expression (trame templates take expressions, inside a double-quoted HTML attribute: single quotes only):
# ignore keys typed into text fields, sliders and open menus, keep the browser's own use of the handled keys out of
# the way. A menu's closed field (the speed, a filter: a read-only input) or a check box that keeps the focus after a
# click does not take typing (read-only, or an input mode of 'none'), so the keys stay the studio's.
_KEYS_JS = "[" + ", ".join(f"'{k}'" for k in KEYS) + "]"
_TYPING_JS = (
    "(e.target.tagName === 'INPUT' && !e.target.readOnly && e.target.inputMode !== 'none'"
    " && !['checkbox', 'radio', 'button'].includes(e.target.type))"
    " || ['TEXTAREA', 'SELECT'].includes(e.target.tagName) || e.target.isContentEditable"
    " || e.target.getAttribute('role') === 'slider' || !!e.target.closest('.v-overlay')"
)
LISTENER_JS = (
    f"utils.get('document').addEventListener('keydown', (e) => ({_TYPING_JS}"
    f" || e.ctrlKey || e.metaKey || e.altKey || !{_KEYS_JS}.includes(e.key)"
    " ? 0 : (e.preventDefault(), trigger('key_pressed', [e.key]))))"
)


class KeyTarget(Protocol):
    """What the keys act on (the Studio is one)."""

    state: Any
    session: Session

    def match_label(self) -> None: ...

    def reset_label(self) -> None: ...


def press(studio: KeyTarget, key: str) -> None:
    """Act on one key (anything not in KEYS is ignored: the page is not trusted to filter)."""
    s, n = studio.state, studio.session.num_frames
    frames = {"ArrowLeft": int(s.frame or 0) - 1, "ArrowRight": int(s.frame or 0) + 1, "Home": 0, "End": n - 1}
    if key == " ":
        s.playing = not s.playing
    elif key in frames:
        s.playing = False
        s.frame = int(np.clip(frames[key], 0, n - 1))
    elif key in ("[", "]"):
        s.loop_range = with_end(s.loop_range, "in" if key == "[" else "out", int(s.frame or 0), n)
    elif key in ("m", "M"):
        studio.match_label()
    elif key in ("r", "R"):
        studio.reset_label()
    elif key.isdigit() and 1 <= int(key) <= len(studio.session.class_names):
        s.key_slider = int(key) - 1
    elif key in ("ArrowUp", "ArrowDown"):
        name = f"w_{int(s.key_slider or 0)}"
        step = SLIDER_STEP if key == "ArrowUp" else -SLIDER_STEP
        s[name] = round(float(np.clip(float(s[name] or 0.0) + step, -1.0, 1.0)), 2)
    elif key == "?":
        s.show_keys = not s.show_keys
