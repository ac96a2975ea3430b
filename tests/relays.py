"""Stand-ins for what sits between a user and the studio: an SSH port forward and a reverse proxy with a
path prefix (the single-port browser tests)."""

from __future__ import annotations


class TcpRelay:
    """A local port that forwards every connection to another (what `ssh -L` does), for the single-port test."""

    def __init__(self, target_port: int):
        import socket
        import threading

        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.target = target_port
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        import socket
        import threading

        while True:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            upstream = socket.create_connection(("127.0.0.1", self.target))
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    @staticmethod
    def _pump(src, dst):
        try:
            while data := src.recv(65536):
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for sock in (src, dst):
                try:
                    sock.shutdown(2)
                except OSError:
                    pass

    def close(self):
        self.server.close()


class PrefixProxy:
    """A reverse proxy that serves the studio under /imm/ and passes Host and Origin through, as nginx does with
    `location /imm/ { proxy_pass http://127.0.0.1:8080/; proxy_set_header Host $host; }` (plus the upgrade headers)."""

    def __init__(self):
        import threading

        self.target, self.port = 0, 0
        ready = threading.Event()
        threading.Thread(target=self._serve, args=(ready,), daemon=True).start()  # its own loop: Playwright has the main one
        ready.wait(10)

    def _serve(self, ready) -> None:
        import asyncio

        from aiohttp import web

        self.loop = asyncio.new_event_loop()
        app = web.Application()
        app.router.add_route("*", "/imm/{tail:.*}", self.handle)
        runner = web.AppRunner(app)
        self.loop.run_until_complete(runner.setup())
        site = web.TCPSite(runner, "127.0.0.1", 0)
        self.loop.run_until_complete(site.start())
        self.port = runner.addresses[0][1]
        ready.set()
        self.loop.run_forever()

    async def handle(self, request):
        import asyncio

        from aiohttp import ClientSession, WSMsgType, web

        url = f"http://127.0.0.1:{self.target}/{request.match_info['tail']}"
        skip = {"connection", "upgrade", "content-length", "transfer-encoding", "sec-websocket-key", "sec-websocket-version",
                "sec-websocket-extensions"}
        headers = {k: v for k, v in request.headers.items() if k.lower() not in skip}  # Host and Origin kept
        async with ClientSession(auto_decompress=False) as session:
            if request.headers.get("Upgrade", "").lower() == "websocket":
                browser = web.WebSocketResponse(max_msg_size=0)
                await browser.prepare(request)
                async with session.ws_connect(url, headers=headers, max_msg_size=0) as studio:
                    async def pump(a, b):
                        async for m in a:
                            if m.type not in (WSMsgType.TEXT, WSMsgType.BINARY):
                                break
                            await (b.send_str(m.data) if m.type == WSMsgType.TEXT else b.send_bytes(m.data))
                        await b.close()
                    await asyncio.wait([asyncio.ensure_future(pump(browser, studio)), asyncio.ensure_future(pump(studio, browser))],
                                       return_when=asyncio.FIRST_COMPLETED)
                return browser
            async with session.request(request.method, url, params=request.query, headers=headers, data=await request.read(),
                                       allow_redirects=False) as up:
                body = await up.read()
                keep = {k: v for k, v in up.headers.items() if k.lower() not in skip}
                return web.Response(status=up.status, body=body, headers=keep)

    def close(self):
        self.loop.call_soon_threadsafe(self.loop.stop)
