// Loaded before trame's client (explorer/serving/page_shell.py). wslink's client asks the browser to deliver each binary
// websocket message as a Blob, then reads it back with two asynchronous Blob reads; on a busy machine that took
// ~20 ms between a picture's arrival and its display. Here the socket delivers an ArrayBuffer, handed to wslink
// in a Blob-shaped wrapper whose reads resolve at once.
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
    ws.binaryType = "arraybuffer";
    Object.defineProperty(ws, "binaryType", { get: () => "blob", set: () => {} });  // wslink sets "blob"
    let onmessage = null;
    Object.defineProperty(ws, "onmessage", { get: () => onmessage, set: (fn) => { onmessage = fn; } });
    ws.addEventListener("message", (e) => {
      if (onmessage) onmessage(e.data instanceof ArrayBuffer ? { type: e.type, data: new Bytes(e.data) } : e);
    });
    return ws;
  }
  BytesWebSocket.prototype = Native.prototype;
  Object.assign(BytesWebSocket, { CONNECTING: 0, OPEN: 1, CLOSING: 2, CLOSED: 3 });
  window.WebSocket = BytesWebSocket;
})();
