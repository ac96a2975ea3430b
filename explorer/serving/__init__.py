"""Serving: the processes and the network around the page, no UI of its own.

launcher.py (`imm explore`'s one public port, aiohttp) -> zygote.py (loads everything once, forks) -> worker.py (one
studio process per browser tab: builds the page of explorer/ui/app.py and serves it); proxy.py forwards a tab's HTTP
and websocket to its process, page_shell.py is the page's index.html, upload_reader.py reads uploaded leaders out of
process. What they rely on in trame and wslink beyond their documented API goes through
explorer/trame_adapter.py.

Serving imports the page (explorer.ui) in two places only: the worker, which builds it, and the zygote's preload,
which imports it before forking so that no tab imports it again.
"""
