// The controls' PIN, for viewer.js and graph.js: marie view prints the page's address with
// #pin=...; the page keeps it for this tab (sessionStorage, shared by the viewer and the graph)
// and takes it out of the address bar. Without one, the first control asks for it.
'use strict';
const controlPin = {
  key: 'marie-viewer-pin',
  take() {
    const p = new URLSearchParams(location.hash.slice(1)).get('pin');
    if (p) {
      sessionStorage.setItem(this.key, p);
      history.replaceState(null, '', location.pathname + location.search);
    }
  },
  get() {
    let p = sessionStorage.getItem(this.key);
    if (!p) {
      p = prompt('PIN of the controls (marie view prints it in the address, after #pin=)') || '';
      if (p) sessionStorage.setItem(this.key, p);
    }
    return p;
  },
  // The server said the PIN was wrong: ask again next time.
  refused(text) { if (/^wrong PIN/.test(text)) sessionStorage.removeItem(this.key); },
};
controlPin.take();
