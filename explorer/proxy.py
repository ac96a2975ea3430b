"""Single-port serving: the launcher forwards each tab's HTTP requests and websocket to its studio process, so
only the launcher's one port needs to be reachable (an SSH tunnel, a reverse proxy with a path prefix).

A tab's studio lives under /s/<token>/ on the launcher's port. trame's page uses relative asset URLs
(<base href=".">) and opens its websocket at <page path>/ws, so nothing in the page needs rewriting. The
token is random and unguessable; the websocket also has to come from the studio's own origin, and its messages
are capped in size. Each studio process has its own random wslink secret (not wslink's default): the proxy puts
it into the browser's hello, so the page never knows it and another local user who finds a studio's loopback
port cannot log in to it.
"""

from __future__ import annotations

from collections.abc import Callable

from aiohttp import ClientSession, WSMsgType, web

MAX_MESSAGE_BYTES = 32 * 1024 * 1024  # an upload is at most 20 MB (explorer/session.py) plus framing
HOP_HEADERS = {"connection", "keep-alive", "transfer-encoding", "upgrade", "host", "content-length", "content-encoding"}


async def forward_http(request: web.Request, port: int, tail: str) -> web.StreamResponse:
    """GET the same path from the studio process on 127.0.0.1:port and stream the answer back."""
    url = f"http://127.0.0.1:{port}/{tail}"
    async with ClientSession(auto_decompress=False) as session:
        async with session.request(request.method, url, params=request.query, allow_redirects=False,
                                   headers={k: v for k, v in request.headers.items() if k.lower() not in HOP_HEADERS}) as upstream:
            response = web.StreamResponse(status=upstream.status,
                                          headers={k: v for k, v in upstream.headers.items() if k.lower() not in HOP_HEADERS})
            if "Content-Encoding" in upstream.headers:
                response.headers["Content-Encoding"] = upstream.headers["Content-Encoding"]
            await response.prepare(request)
            async for chunk in upstream.content.iter_chunked(1 << 16):
                await response.write(chunk)
            await response.write_eof()
            return response


HEADER = 12  # wslink's chunk header: message id, offset, total size (uint32 little-endian each)


def with_secret(frame: bytes, secret: str) -> bytes:
    """A browser's wslink hello (one msgpack chunk) with the studio's secret in it; any other frame unchanged."""
    import msgpack

    if len(frame) < HEADER or int.from_bytes(frame[4:8], "little") != 0 or int.from_bytes(frame[8:12], "little") != len(frame) - HEADER:
        return frame  # not a whole message in one chunk: a hello always is (the worker refuses the rest unauthenticated)
    try:
        message = msgpack.unpackb(frame[HEADER:])
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
        return frame
    if not (isinstance(message, dict) and message.get("method") == "wslink.hello" and message.get("args")
            and isinstance(message["args"][0], dict)):
        return frame
    message["args"][0]["secret"] = secret
    body = msgpack.packb(message)
    return frame[:4] + (0).to_bytes(4, "little") + len(body).to_bytes(4, "little") + body


async def forward_websocket(request: web.Request, port: int, tail: str, secret: str | None = None,
                            on_message: Callable[[], None] = lambda: None) -> web.WebSocketResponse:
    """Relay a websocket between the browser and the studio process, both directions, text and binary; the
    browser's hello carries the studio's secret; `on_message` is called for every message relayed."""
    import asyncio

    browser = web.WebSocketResponse(max_msg_size=MAX_MESSAGE_BYTES, autoping=True)
    await browser.prepare(request)
    async with ClientSession() as session:
        async with session.ws_connect(f"http://127.0.0.1:{port}/{tail}", max_msg_size=0, autoping=True) as studio:

            async def pump(source, sink) -> None:
                async for msg in source:
                    on_message()
                    if msg.type == WSMsgType.TEXT:
                        await sink.send_str(msg.data)
                    elif msg.type == WSMsgType.BINARY:
                        await sink.send_bytes(with_secret(msg.data, secret) if secret and sink is studio else msg.data)
                    else:  # close or error: the other side is closed too
                        break
                await sink.close()

            tasks = [asyncio.ensure_future(pump(browser, studio)), asyncio.ensure_future(pump(studio, browser))]
            _, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            for task in pending:
                task.cancel()
    return browser
