// Loaded before trame's client (explorer/serving/page_shell.py). wslink's client asks the browser to deliver each binary
// websocket message as a Blob, then reads it back with two asynchronous Blob reads; on a busy machine that took
// ~20 ms between a picture's arrival and its display. Here the socket delivers an ArrayBuffer, handed to wslink
// in a Blob-shaped wrapper whose reads resolve at once. The wrapper also sends the tab to a fresh studio when the
// launcher found its studio process stuck, and loads the page again when its layout never came (below).
(() => {
  class Bytes {
    constructor(buffer, start = 0, end = buffer.byteLength) { this.buffer = buffer; this.start = start; this.end = end; }
    get size() { return this.end - this.start; }
    slice(from = 0, to = this.size) { return new Bytes(this.buffer, this.start + from, this.start + Math.min(to, this.size)); }
    arrayBuffer() { return Promise.resolve(this.buffer.slice(this.start, this.end)); }
  }
  const Native = window.WebSocket;
  function BytesWebSocket(...args) {
    const ws = new Native(...args);
    link.opened = performance.now();
    ws.binaryType = "arraybuffer";
    Object.defineProperty(ws, "binaryType", { get: () => "blob", set: () => {} });  // wslink sets "blob"
    let onmessage = null;
    Object.defineProperty(ws, "onmessage", { get: () => onmessage, set: (fn) => { onmessage = fn; } });
    ws.addEventListener("message", (e) => {
      if (!link.messages++) { forgetTries(); watchLayout(); }
      if (onmessage) onmessage(e.data instanceof ArrayBuffer ? { type: e.type, data: new Bytes(e.data) } : e);
    });
    ws.addEventListener("close", (e) => {
      link.closed = e.code;
      if (e.code === NO_ANSWER && !link.messages) freshStudio();
    });
    return ws;
  }
  // What the page's websocket has done (window.__immLink: when it opened, messages received, its close code) and the
  // stylesheets and scripts the page still waits for (`waiting()`): read by a test whose page never showed its studio.
  const link = window.__immLink = { opened: null, messages: 0, closed: null, waiting: () => stillLoading() };
  // A studio process that did not answer its page is replaced by the launcher, which closes the websocket with
  // NO_ANSWER (explorer/serving/proxy.py SILENT_CLOSE): the tab goes to the front page for a fresh studio, with the view
  // its address names, twice in a row at most (counted in the tab's sessionStorage until a studio answers).
  const NO_ANSWER = 4013, TRIES = "imm-studio-retries", MAX_TRIES = 2;
  const forgetTries = () => { try { sessionStorage.removeItem(TRIES); } catch (e) {} };
  // trame's client draws the page once every stylesheet and script its state names has loaded, and waits for ever on
  // one that never arrives: a page whose studio answers but whose layout has not appeared LAYOUT_S later is loaded
  // again, once in a row (the studio keeps its session across a reload), and tells the launcher which files it was
  // still waiting for (explorer/serving/launcher.py LAYOUT_LATE_S, the same time).
  const LAYOUT_S = 20, RELOADED = "imm-studio-reloaded";
  const stillLoading = () => {
    const done = new Set(performance.getEntriesByType("resource").map((r) => r.name));
    return [...document.querySelectorAll("script[src], link[rel=stylesheet]")].map((e) => e.src || e.href)
      .filter((u) => !done.has(u)).map((u) => new URL(u).pathname).join(" ");
  };
  function watchLayout() {
    setTimeout(() => {
      let again = false;
      try {
        if (document.querySelector(".v-application")) { sessionStorage.removeItem(RELOADED); return; }
        again = !sessionStorage.getItem(RELOADED);
        sessionStorage.setItem(RELOADED, "1");
      } catch (e) { return; }
      if (!again) return;
      try { navigator.sendBeacon("layout-late", stillLoading()); } catch (e) {}
      location.reload();
    }, LAYOUT_S * 1000);
  }
  function freshStudio() {
    let tries = MAX_TRIES;
    try { tries = Number(sessionStorage.getItem(TRIES)) || 0; sessionStorage.setItem(TRIES, String(tries + 1)); } catch (e) {}
    if (tries < MAX_TRIES) {
      location.replace(new URL("../../" + location.search, location.href).href);
    } else {
      forgetTries();
      document.body.insertAdjacentHTML("afterbegin", '<p id="imm-no-answer" style="position:fixed;z-index:9999;top:0;' +
        'left:0;right:0;margin:0;padding:1em;background:#fff;color:#b00020;font-family:sans-serif">The studio did not ' +
        "answer this tab (twice): reload the page to try again.</p>");
    }
  }
  BytesWebSocket.prototype = Native.prototype;
  Object.assign(BytesWebSocket, { CONNECTING: 0, OPEN: 1, CLOSING: 2, CLOSED: 3 });
  window.WebSocket = BytesWebSocket;
})();
