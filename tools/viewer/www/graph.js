// The system graph: hosts -> components -> ports -> channels, live from the managers' status and
// the components' heartbeats; a component is restarted, stopped, started or moved with signed
// orders (the viewer server signs); the managers' placement decisions as they happen.
'use strict';
const $ = (id) => document.getElementById(id);
const body = document.body;
const SVG = 'http://www.w3.org/2000/svg';
let ws = null, retry = 0, controls = false;
let S = fresh();

function fresh() {
  return { hosts: {}, hb: {}, rates: {}, decisions: [], selected: null };
}

function notice(text) { $('notice').textContent = new Date().toLocaleTimeString() + '  ' + text; }
function banner(text, level) {
  const b = $('banner');
  b.className = text ? 'banner ' + (level || 'warn') : 'banner hidden';
  b.textContent = text || '';
}

function connect() {
  const url = (location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/ws';
  try { ws = new WebSocket(url); } catch (e) { setTimeout(connect, 1000); return; }
  ws.onopen = () => { retry = 0; body.dataset.connected = '1'; S = fresh(); banner(''); };
  ws.onmessage = (ev) => {
    let m;
    try { m = JSON.parse(ev.data); } catch (e) { notice('bad frame from the server'); return; }
    try { handle(m); } catch (e) { banner('page error: ' + e.message, 'error'); }
  };
  ws.onclose = () => {
    body.dataset.connected = '0';
    banner('connection lost, retrying…', 'error');
    retry = Math.min(retry + 1, 5);
    setTimeout(connect, 500 * retry);
  };
}

function send(obj) { if (ws && ws.readyState === 1) ws.send(JSON.stringify(obj)); }

function handle(m) {
  if (m.type === 'hello') {
    controls = !!m.controls;
    body.dataset.state = 'ready';
    $('mode').textContent = (m.mode === 'log' ? 'log' : 'live bus') + (controls ? ', controls enabled' : ', controls disabled');
  } else if (m.type === 'notice') {
    notice(m.text);
    controlPin.refused(m.text);
  } else if (m.type === 'msg') {
    onMsg(m);
  }
}

// A port's rate: messages per second between two heartbeats.
function rate(key, msgs, t) {
  const r = S.rates[key];
  if (r && t > r.t && msgs >= r.m) r.hz = (msgs - r.m) / ((t - r.t) / 1e6);
  S.rates[key] = { m: msgs, t: t, hz: r ? r.hz : 0 };
}

// A message frame: f.k says what it is, f.msg is the message with its .lcm field names.
function onMsg(f) {
  const m = f.msg;
  switch (f.k) {
  case 'am': {
    const h = S.hosts[m.host] || (S.hosts[m.host] = {});
    h.comps = m.components; h.seen = Date.now(); h.leader = m.balance_leader; h.term = m.balance_term;
    if (m.balance_last && m.balance_last !== h.last) S.decisions.unshift(m.host + ': ' + m.balance_last);
    h.last = m.balance_last;
    S.decisions.length = Math.min(S.decisions.length, 20);
    break;
  }
  case 'hb':
    S.hb[m.component] = m;
    for (const p of m.ports) rate(m.component + '/' + p.name, p.msgs, f.t);
    break;
  case 'event':
    if (m.kind === 'balance') {
      S.decisions.unshift(m.source + ': ' + m.text);
      S.decisions.length = Math.min(S.decisions.length, 20);
    }
    break;
  }
}

function el(tag, attrs, parent, text) {
  const e = document.createElementNS(SVG, tag);
  for (const k in attrs) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  if (parent) parent.appendChild(e);
  return e;
}

const STATE_COLOR = { running: '#a5d6a7', degraded: '#ffe082', paused: '#ffcc80', starting: '#e6ee9c',
  backoff: '#ffab91', failed: '#ef9a9a', hung: '#ef9a9a', stopped: '#e0e0e0', waiting: '#e0e0e0' };

// Hosts stacked on the left with their components; channels in a column on the right; a solid
// edge from a component that publishes, a dashed one to a component that listens.
function draw() {
  const svg = $('graph');
  while (svg.firstChild) svg.removeChild(svg.firstChild);
  const now = Date.now();
  const hosts = Object.keys(S.hosts).sort();
  const compPos = {}, chans = {};
  let y = 10, ncomp = 0;
  for (const h of hosts) {
    const H = S.hosts[h], lost = now - H.seen > 3000;
    const comps = (H.comps || []).slice().sort((a, b) => a.name.localeCompare(b.name));
    const height = 26 + comps.length * 34;
    el('rect', { class: 'host', x: 10, y: y, width: 420, height: height, rx: 6 }, svg);
    el('text', { class: 'host-title', x: 20, y: y + 17 }, svg,
       h + (lost ? '  (lost)' : '') + (H.leader === h ? '  ★ decides placement (term ' + H.term + ')' : ''));
    let cy = y + 26;
    for (const c of comps) {
      // c: an am_component_status_t; hb: the component's heartbeat_t
      const hb = S.hb[c.name] || {};
      const g = el('g', { 'data-comp': c.name }, svg);
      el('rect', { class: 'comp' + (S.selected === c.name ? ' sel' : ''), x: 20, y: cy, width: 400, height: 28, rx: 4,
                   fill: lost ? '#e0e0e0' : (STATE_COLOR[c.state] || '#e0e0e0') }, g);
      el('text', { x: 28, y: cy + 12 }, g, c.name + '  ' + c.state);
      el('text', { x: 28, y: cy + 24 }, g, 'cpu ' + (c.cpu || 0).toFixed(1) + '%  rss ' + ((c.rss || 0) / 1048576).toFixed(1) +
         'M  restarts ' + c.restarts + '  bad input ' + (hb.bad_input || 0));
      g.addEventListener('click', () => select(c.name, h));
      compPos[c.name] = { x: 420, y: cy + 14 };
      for (const p of hb.ports || []) {
        if (!p.channel) continue;
        const out = p.direction === 1;      // port_status_t.OUT
        const ch = chans[p.channel] || (chans[p.channel] = { type: p.type, pub: [], sub: [], hz: 0 });
        (out ? ch.pub : ch.sub).push(c.name);
        if (out) ch.hz += (S.rates[c.name + '/' + p.name] || {}).hz || 0;
      }
      cy += 34;
      ncomp++;
    }
    y += height + 10;
  }
  const names = Object.keys(chans).sort();
  let edges = 0;
  names.forEach((n, i) => {
    const ch = chans[n], cy = 14 + i * 30;
    for (const c of ch.pub) {
      const p = compPos[c];
      el('path', { class: 'edge-out', d: 'M' + p.x + ',' + p.y + ' C560,' + p.y + ' 560,' + (cy + 10) + ' 640,' + (cy + 10) }, svg);
      edges++;
    }
    for (const c of ch.sub) {
      const p = compPos[c];
      el('path', { class: 'edge-in', d: 'M640,' + (cy + 14) + ' C560,' + (cy + 14) + ' 560,' + p.y + ' ' + p.x + ',' + p.y }, svg);
      edges++;
    }
    el('rect', { class: 'chan', x: 640, y: cy, width: 330, height: 26, rx: 4, 'data-channel': n }, svg);
    el('text', { x: 648, y: cy + 11 }, svg, n);
    el('text', { x: 648, y: cy + 23 }, svg, (ch.type || 'raw') + '  ' + ch.hz.toFixed(1) + ' msg/s');
  });
  svg.setAttribute('height', Math.max(y, 20 + names.length * 30, 200));
  body.dataset.hosts = String(hosts.length);
  body.dataset.components = String(ncomp);
  body.dataset.channels = String(names.length);
  body.dataset.edges = String(edges);
  const leader = hosts.map((h) => S.hosts[h].leader).find((l) => l) || '';
  body.dataset.leader = leader;
  $('leader').textContent = leader ? leader + ' decides' : '(no balance: section)';
  $('placement').innerHTML = '';
  for (const d of S.decisions) { const li = document.createElement('li'); li.textContent = d; $('placement').appendChild(li); }
  showSelected();
}

function select(name, host) {
  S.selected = name;
  body.dataset.selected = name;
  const sel = $('move-host');
  sel.innerHTML = '';
  for (const h of Object.keys(S.hosts).sort()) {
    if (h === host) continue;
    const o = document.createElement('option'); o.value = o.textContent = h; sel.appendChild(o);
  }
  draw();
}

function showSelected() {
  const n = S.selected;
  $('sel-name').textContent = n || '(click one)';
  $('sel-controls').className = n && controls ? '' : 'hidden';
  const tb = $('sel-table').tBodies[0];
  tb.innerHTML = '';
  if (!n) return;
  const hb = S.hb[n] || {};
  const rows = [['host', hb.host || ''], ['messages in / out', (hb.msgs_in || 0) + ' / ' + (hb.msgs_out || 0)],
                ['drops / bad input / overruns', (hb.drops || 0) + ' / ' + (hb.bad_input || 0) + ' / ' + (hb.overruns || 0)]];
  for (const p of hb.ports || [])
    rows.push([(p.direction === 1 ? 'out ' : 'in ') + p.name, p.channel + ' (' + ((S.rates[n + '/' + p.name] || {}).hz || 0).toFixed(1) + ' msg/s)']);
  for (const r of rows) {
    const tr = tb.insertRow();
    tr.insertCell().textContent = r[0];
    tr.insertCell().textContent = r[1];
  }
}

for (const b of document.querySelectorAll('#sel-controls button')) {
  b.addEventListener('click', () => {
    if (!S.selected) return;
    const o = { op: 'order', cmd: b.dataset.cmd, target: S.selected, pin: controlPin.get() };
    if (b.dataset.cmd === 'move') o.host = $('move-host').value;
    send(o);
  });
}

setInterval(draw, 500);
connect();
