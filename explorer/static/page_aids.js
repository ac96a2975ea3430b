// Small aids of the page that templates cannot express.
//
// A studio's address (/s/<session>/...) is its tab's: the front page's claim notes it in the tab's sessionStorage
// (explorer/serving/launcher.py CLAIM_PAGE), which a reload keeps and a new tab does not have. Opened in another tab
// (a copied address), the page goes to the front page with the view the address names, for a studio of its own,
// before it connects to this one (another browser is sent there by the launcher already).
(() => {
  const mine = (path) => path.replace(/index\.html$/, '');
  let noted = null;
  try { noted = sessionStorage.getItem('imm-studio-tab'); } catch (e) { return; }
  if (/\/s\/[^/]+\/(index\.html)?$/.test(location.pathname) && (!noted || mine(noted) !== mine(location.pathname))) {
    location.replace(new URL('../../' + location.search, location.href).href);
  }
})();

// The 3D view's joint readout: while the mouse rests over the view (no button pressed: a drag turns the camera), the
// server is told where, at most every HOVER_EVERY_MS, and names the joint drawn there with its speed (explorer/ui/app.py
// hover_joint, state `joint_hover`); leaving the view clears it.
(() => {
  const HOVER_EVERY_MS = 80;
  let last = 0;
  let due = null;
  const send = (where) => window.trame && window.trame.trigger('hover_joint', [where]);
  document.addEventListener('mousemove', (e) => {
    const img = e.target.closest && e.target.closest('.imm-scene img');
    if (!img || e.buttons) return;
    const r = img.getBoundingClientRect();
    const where = [(e.clientX - r.left) / r.width, (e.clientY - r.top) / r.height];
    clearTimeout(due);
    const wait = last + HOVER_EVERY_MS - performance.now();
    if (wait <= 0) { last = performance.now(); send(where); } else due = setTimeout(() => { last = performance.now(); send(where); }, wait);
  }, {passive: true});
  document.addEventListener('mouseout', (e) => {
    if (e.target.closest && e.target.closest('.imm-scene img') && !(e.relatedTarget && e.relatedTarget.closest && e.relatedTarget.closest('.imm-scene img'))) {
      clearTimeout(due);
      send(null);
    }
  }, {passive: true});
})();

// A table row brought into sight once the page has drawn it (the review's current row after "Next worst" or a map
// click): window.immScrollIntoView(selector), called from a state change, waits a frame for the table to render it.
window.immScrollIntoView = (selector) => requestAnimationFrame(() => {
  const el = document.querySelector(selector);
  if (el) el.scrollIntoView({block: 'nearest'});
});

// How many of the review's model column groups fit its table (explorer/ui/review_panel.py: `fixed` px of sequence and
// class columns, `per` px a model): window.immWatchFit(selector, fixed, per, key) keeps the count in the state key
// `key` as the table's pane is resized, so the server shows no more models than fit and the table never scrolls
// sideways unseen.
window.immWatchFit = (selector, fixed, per, key) => requestAnimationFrame(() => {
  const el = document.querySelector(selector);
  if (!el || el.immFit) return;
  el.immFit = new ResizeObserver(() => {
    const count = Math.max(1, Math.floor((el.clientWidth - fixed) / per));
    if (window.trame.state.get(key) !== count) window.trame.state.set(key, count);
  });
  el.immFit.observe(el);
});

// A value being typed into one of the number fields beside the sliders (.imm-value) stays as typed until Enter or
// leaving the field sets it: the page re-renders whenever the server changes any state (a reaction settling, the
// 'reads as' panel), and Vue writes each field's bound value back into it then, which threw the typing away.
(() => {
  const native = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, 'value');
  const typing = new WeakSet();
  const guard = (el) => {
    if (Object.prototype.hasOwnProperty.call(el, 'value')) return;
    Object.defineProperty(el, 'value', {
      configurable: true,
      get() { return native.get.call(this); },
      set(v) { if (!(typing.has(this) && document.activeElement === this)) native.set.call(this, v); },
    });
  };
  const field = (e) => e.target && e.target.classList && e.target.classList.contains('imm-value') ? e.target : null;
  document.addEventListener('input', (e) => { const el = field(e); if (el) { guard(el); typing.add(el); } }, true);
  // committed (Enter, or the field left): the value the server sets from it shows again
  const done = (e) => { const el = field(e); if (el) typing.delete(el); };
  document.addEventListener('change', done, true);
  document.addEventListener('focusout', done, true);
})();
