"""What a panel of the page is given: the Page (the user's session, the page's state and controllers, the trigger
registry, and `guarded`), plus the few callbacks of the Studio it calls, named in its constructor. No panel holds the
Studio (explorer/ui/app.py) or reaches into another module's private attributes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from explorer.session.session import Session


@dataclass(frozen=True)
class Page:
    """The page one user sees. `state` and `ctrl` are the trame server's state and controller; `trigger(name)` registers
    a function the page awaits (a download); `guarded(fn)` is `fn` with its errors in the page's one-line alert."""

    session: Session
    state: Any
    ctrl: Any
    trigger: Callable[[str], Callable[[Callable], Callable]]
    guarded: Callable[[Callable], Callable]
