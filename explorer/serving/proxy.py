"""Single-port serving: the launcher forwards each tab's HTTP requests and websocket to its studio process, so
only the launcher's one port needs to be reachable (an SSH tunnel, a reverse proxy with a path prefix).

A tab's studio lives under /s/<token>/ on the launcher's port. trame's page uses relative asset URLs
(<base href=".">) and opens its websocket at <page path>/ws, so nothing in the page needs rewriting. The
token is random and unguessable; the websocket also has to come from the studio's own origin, and what its
messages claim is capped before the studio allocates it (InboundBudget). Each studio process has its own random
wslink secret (not wslink's default): the proxy puts it into the browser's hello, so the page never knows it and
another local user who finds a studio's loopback port cannot log in to it.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

from aiohttp import ClientError, ClientSession, WSCloseCode, WSMsgType, web

from explorer.trame_adapter import MAX_FRAME_BYTES, WSLINK_HEADER, WSLINK_HELLO

MAX_MESSAGE_BYTES = 32 * 1024 * 1024  # an upload is at most 20 MB (explorer/session/session.py) plus framing
MAX_PENDING_BYTES = 32 * 1024 * 1024  # all messages a studio process is still receiving, over all its websockets
HEARTBEAT_S = 20.0  # a browser that vanished without closing (network lost) is noticed within 1.5x this
# The close code a tab's websocket gets when its studio process did not answer: the page asks the front page for a fresh
# studio (explorer/static/websocket_bytes.js). 4000-4999 are the application's own codes.
SILENT_CLOSE = 4013
HOP_HEADERS = {"connection", "keep-alive", "transfer-encoding", "upgrade", "host", "content-length", "content-encoding"}


async def forward_http(request: web.Request, port: int, tail: str, answer_s: float | None = None,
                       on_silent: Callable[[str], None] = lambda why: None) -> web.StreamResponse | None:
    """GET the same path from the studio process on 127.0.0.1:port and stream the answer back; None, after
    `on_silent(why)`, when the studio process has not answered within `answer_s` (it is stuck)."""
    url = f"http://127.0.0.1:{port}/{tail}"
    async with ClientSession(auto_decompress=False) as session:
        try:
            async with asyncio.timeout(answer_s):  # to its answer's headers; the body streams without a limit
                upstream = await session.request(request.method, url, params=request.query, allow_redirects=False,
                                                  headers={k: v for k, v in request.headers.items() if k.lower() not in HOP_HEADERS})
        except (TimeoutError, OSError, ClientError) as err:
            on_silent(_silence(err, answer_s, f"its page's request for /{tail[:80]}"))
            return None
        async with upstream:
            response = web.StreamResponse(status=upstream.status,
                                          headers={k: v for k, v in upstream.headers.items() if k.lower() not in HOP_HEADERS})
            if "Content-Encoding" in upstream.headers:
                response.headers["Content-Encoding"] = upstream.headers["Content-Encoding"]
            # a tab closed or reloaded before or during the answer (a large script still streaming) is not an error:
            # stop sending (aiohttp then finishes the request as a client that went away)
            with contextlib.suppress(ConnectionResetError):
                await response.prepare(request)
                async for chunk in upstream.content.iter_chunked(1 << 16):
                    await response.write(chunk)
                await response.write_eof()
            return response


def _silence(err: BaseException, answer_s: float | None, what: str) -> str:
    """Why a studio process is taken for stuck, in words: it did not answer `what` in time, or could not be reached."""
    if isinstance(err, TimeoutError) and not isinstance(err, ClientError):
        return f"it did not answer {what} within {answer_s:g} s"
    return f"{what} could not reach it ({type(err).__name__}: {' '.join(str(err).split())[:200]})"


HEADER = WSLINK_HEADER  # wslink's chunk header: message id, offset, total size (uint32 little-endian each)


class InboundBudget:
    """What a browser's messages may make one studio process allocate. wslink's receiver (wslink/chunking.py
    UnChunker) allocates a message's whole claimed size at its first chunk, up to 4 GiB once a client has logged in,
    so a 13-byte frame could claim a gigabyte: each chunk's claim is checked here before it is forwarded."""

    def __init__(self):
        self.pending: dict[tuple[int, int], list[int]] = {}  # (websocket, message id) -> [claimed size, bytes received]

    def admit(self, websocket: int, frame: bytes) -> str | None:
        """None if `frame` may go on; else why not (the websocket is then closed)."""
        if len(frame) < HEADER:
            return f"a {len(frame)}-byte frame, shorter than a chunk header"
        key = (websocket, int.from_bytes(frame[0:4], "little"))
        offset, total = int.from_bytes(frame[4:8], "little"), int.from_bytes(frame[8:12], "little")
        size = len(frame) - HEADER
        entry = self.pending.get(key)
        if entry is None:
            if total > MAX_MESSAGE_BYTES:
                return f"a message claiming {total} bytes (at most {MAX_MESSAGE_BYTES})"
            owed = sum(claimed for claimed, _ in self.pending.values())
            if owed + total > MAX_PENDING_BYTES:
                return f"messages claiming {owed + total} bytes at once (at most {MAX_PENDING_BYTES})"
            entry = [total, 0]
        elif entry[0] != total:
            return "a chunk whose message size differs from its first chunk's"
        if offset + size > total:
            return "a chunk beyond the end of its message"
        entry[1] += size
        if entry[1] >= total:
            self.pending.pop(key, None)
        else:
            self.pending[key] = entry
        return None

    def forget(self, websocket: int) -> None:
        """A websocket closed: the studio dropped its unfinished messages."""
        for key in [k for k in self.pending if k[0] == websocket]:
            del self.pending[key]


def with_secret(frame: bytes, secret: str) -> bytes:
    """A browser's wslink hello (one msgpack chunk) with the studio's secret in it; any other frame unchanged."""
    import msgpack

    if len(frame) < HEADER or int.from_bytes(frame[4:8], "little") != 0 or int.from_bytes(frame[8:12], "little") != len(frame) - HEADER:
        return frame  # not a whole message in one chunk: a hello always is (the worker refuses the rest unauthenticated)
    try:
        message = msgpack.unpackb(frame[HEADER:])
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
        return frame
    if not (isinstance(message, dict) and message.get("method") == WSLINK_HELLO and message.get("args")
            and isinstance(message["args"][0], dict)):
        return frame
    message["args"][0]["secret"] = secret
    body = msgpack.packb(message)
    return frame[:4] + (0).to_bytes(4, "little") + len(body).to_bytes(4, "little") + body


async def forward_websocket(request: web.Request, port: int, tail: str, secret: str | None = None,
                            budget: InboundBudget | None = None,
                            on_message: Callable[[], None] = lambda: None,
                            answer_s: float | None = None,
                            on_silent: Callable[[str], None] = lambda why: None) -> web.WebSocketResponse:
    """Relay a websocket between the browser and the studio process, both directions, text and binary; the
    browser's hello carries the studio's secret; the browser's chunks are checked against `budget`; `on_message` is
    called for every message relayed. A studio process that has not accepted the websocket and sent its first message
    within `answer_s` (it answers the hello in milliseconds) is taken for stuck: the browser's websocket is closed with
    SILENT_CLOSE (the page then asks for a fresh studio: explorer/static/websocket_bytes.js) and `on_silent(why)` called."""
    budget = budget or InboundBudget()
    # No permessage-deflate: the pictures are JPEG already, deflating them costs a thread hop per frame, and a tab
    # closing mid-send would leave aiohttp's shielded compress-and-send task with an exception no one retrieves.
    # A frame (one chunk of a message) at most the size a studio process accepts: a larger one is refused here, in one
    # close, rather than by the studio mid-relay.
    browser = web.WebSocketResponse(max_msg_size=MAX_FRAME_BYTES, autoping=True, heartbeat=HEARTBEAT_S, compress=False)
    await browser.prepare(request)
    connection = id(browser)
    progress = {"browser": 0, "studio": 0}  # messages relayed each way, for the line a silent studio gets
    try:
        async with asyncio.timeout(answer_s) as deadline, ClientSession() as session:
            async with session.ws_connect(f"http://127.0.0.1:{port}/{tail}", max_msg_size=0, autoping=True) as studio:

                async def pump(source, sink) -> None:
                    inbound = sink is studio
                    side = "browser" if inbound else "studio"
                    # a tab closing mid-message resets its connection: that ends the relay, it is not an error
                    with contextlib.suppress(ConnectionResetError):
                        async for msg in source:
                            on_message()
                            if not inbound and not progress["studio"]:
                                deadline.reschedule(None)  # it answers: no time limit from now on
                            progress[side] += 1
                            if msg.type == WSMsgType.TEXT:
                                await sink.send_str(msg.data)
                            elif msg.type == WSMsgType.BINARY:
                                if inbound and (refused := budget.admit(connection, msg.data)) is not None:
                                    await browser.close(code=WSCloseCode.MESSAGE_TOO_BIG, message=f"refused: {refused}".encode()[:120])
                                    break
                                await sink.send_bytes(with_secret(msg.data, secret) if secret and inbound else msg.data)
                            else:  # close or error: the other side is closed too
                                break
                        await sink.close()

                tasks = [asyncio.ensure_future(pump(browser, studio)), asyncio.ensure_future(pump(studio, browser))]
                try:
                    await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                finally:
                    for task in tasks:
                        task.cancel()
    except (TimeoutError, OSError, ClientError) as err:
        if progress["studio"]:  # it had answered: a connection lost later is the end of the relay, as a close is
            return browser
        why = _silence(err, answer_s, f"its page's websocket ({progress['browser']} messages from the page, none from it)")
        await browser.close(code=SILENT_CLOSE, message=b"the studio process did not answer")
        on_silent(why)
    finally:
        budget.forget(connection)
    return browser
