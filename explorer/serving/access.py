"""Who the launcher (launcher.py) answers: its own page's origin, the host names it serves (DNS rebinding), the access
token, and claims at a bounded rate."""

from __future__ import annotations

import hmac
import secrets
import time
from urllib.parse import urlsplit

TOKEN_COOKIE = "imm_studio_token"
PAGE_COOKIE = "imm_studio_page"  # set by the front page: a claim without an Origin header must carry it
# Claims are rate-limited (a token bucket): CLAIM_BURST at once, then one per CLAIM_EVERY_S. Each claim forks a studio
# process (~0.5 s of CPU), so a script posting claims in a loop would otherwise keep the machine forking.
CLAIM_BURST = 4
CLAIM_EVERY_S = 1.0


class Access:
    def __init__(self, config) -> None:
        """The rules of `config` (launcher.py LaunchConfig): its host, token, no_auth and base_url."""
        self.config = config
        self.page_secret = secrets.token_urlsafe(18)  # the front page's cookie (PAGE_COOKIE)
        self.claim_tokens, self.claim_refilled = float(CLAIM_BURST), time.monotonic()

    def claim_allowed(self) -> bool:
        now = time.monotonic()
        self.claim_tokens = min(CLAIM_BURST, self.claim_tokens + (now - self.claim_refilled) / CLAIM_EVERY_S)
        self.claim_refilled = now
        if self.claim_tokens < 1:
            return False
        self.claim_tokens -= 1
        return True


    def allowed_hosts(self) -> set[str]:
        return {"localhost", "127.0.0.1", "::1", "[::1]", self.config.host} - {"0.0.0.0", "::"}

    def origins(self, request) -> set[str]:
        """The page's own origin as a browser names it: the host it asked for, over the scheme it used (a TLS reverse
        proxy says which in X-Forwarded-Proto), and the public address --base-url names."""
        forwarded = request.headers.get("X-Forwarded-Proto", "").split(",")[0].strip().lower()
        schemes = {request.scheme} | ({forwarded} if forwarded in ("http", "https") else set())
        mine = {f"{scheme}://{request.host}".lower() for scheme in schemes}
        if self.config.base_url:
            public = urlsplit(self.config.base_url)
            mine |= {f"{public.scheme}://{public.netloc}".lower(), f"{public.scheme}://{request.host}".lower()}
        return mine

    def from_the_page(self, request) -> bool:
        """A claim names the page's origin (browsers send Origin with every POST; authorized() compared it), or,
        where a browser's privacy settings withhold it, carries the cookie the front page set. A bare POST does neither."""
        if request.headers.get("Origin", "null") != "null":
            return True
        return hmac.compare_digest(request.cookies.get(PAGE_COOKIE, "").encode(), self.page_secret.encode())

    def same_origin(self, request) -> bool:
        origin = request.headers.get("Origin", "null")
        return origin == "null" or origin.lower() in self.origins(request)

    def host_served(self, request) -> bool:
        return self.config.no_auth or (request.url.host or "") in self.allowed_hosts()

    def public(self, request) -> bool:
        """What /static/ needs: no token (nothing there is secret), but this studio's origin and host names."""
        return self.same_origin(request) and bool(self.config.token or self.host_served(request))

    def authorized(self, request) -> bool:
        """Another web origin is always refused ("null", an origin a browser withholds, counts as none: a claim then
        needs the page's cookie, and a studio's pages its unguessable session path). Then: the access token (first URL
        or cookie) if there is one; without one, a host name this studio serves (a DNS-rebinding page names its own)."""
        if not self.same_origin(request):
            return False
        if self.config.no_auth:
            return True
        if self.config.token is None:
            return self.host_served(request)
        given = request.query.get("token") or request.cookies.get(TOKEN_COOKIE) or ""
        return hmac.compare_digest(given.encode(), self.config.token.encode())
