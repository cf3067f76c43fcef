// marie viewer page: draws what the server streams over /ws (map, poses, laser, path, goals,
// decisions, events, components) and sends playback commands and controls back.
// The page's state is also written to data-* attributes of <body> so tests can read it.
'use strict';

const $ = (id) => document.getElementById(id);
const body = document.body;
const STATES = ['created', 'ready', 'running', 'paused', 'failed', 'exited', 'degraded'];
const PALETTE = ['#1565c0', '#c62828', '#2e7d32', '#ef6c00', '#6a1b9a', '#00838f', '#8d6e63', '#455a64'];

let ws = null, retry = 0, dirty = false;
let S = fresh();

function fresh() {
  return {
    mode: null, controls: false, channels: {},
    map: null, mapCanvas: null,
    est: null, truth: null, laser: null, laserStride: 1, particles: null, path: null,
    goals: {}, currentGoal: null,
    trail: { est: [], truth: [] },
    summary: null, decisions: [], selected: null, liveDec: [],
    comps: {}, am: {}, events: [], restarts: {},
    player: { t: 0, t0: 0, t1: 0, playing: false, speed: 1 },
    now: 0, rxAge: 0, corruptText: '', view: null, goalMode: false, drag: null,
    counts: { laser: 0 }, outs: {}, busText: '',
  };
}

// ---------------------------------------------------------------- connection

function banner(text, level) {
  const b = $('banner');
  if (!text) { b.className = 'banner hidden'; b.textContent = ''; return; }
  b.className = 'banner ' + (level || 'warn');
  b.textContent = text;
}

function notice(text) {
  $('notice').textContent = new Date().toLocaleTimeString() + '  ' + text;
}

function connect() {
  const url = (location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/ws';
  try { ws = new WebSocket(url); } catch (e) { scheduleRetry(); return; }
  ws.onopen = () => {
    retry = 0;
    body.dataset.connected = '1';
    S = fresh();
    banner('');
    applyUrlOptions();
  };
  ws.onmessage = (ev) => {
    let m;
    try { m = JSON.parse(ev.data); } catch (e) { notice('bad frame from the server'); return; }
    try { handle(m); } catch (e) { banner('page error: ' + e.message, 'error'); }
    redraw();
  };
  ws.onclose = () => {
    body.dataset.connected = '0';
    banner('connection lost, retrying…', 'error');
    redraw();
    scheduleRetry();
  };
  ws.onerror = () => {};
}

function scheduleRetry() {
  retry = Math.min(retry + 1, 5);
  setTimeout(connect, 500 * retry);
}

function send(obj) {
  if (ws && ws.readyState === 1) ws.send(JSON.stringify(obj));
}

// ?t=SECONDS seeks the log there (from its start); &paused=1 stops playback.
let urlApplied = false;
function applyUrlOptions() {
  urlApplied = false;
}
function applyUrlOnce() {
  if (urlApplied || S.mode !== 'log') return;
  urlApplied = true;
  const q = new URLSearchParams(location.search);
  if (q.get('paused') === '1') send({ op: 'pause' });
  if (q.get('speed')) send({ op: 'speed', v: Number(q.get('speed')) });
  if (q.get('t') !== null) {
    const t = Math.min(Math.max(S.player.t0 + Number(q.get('t')) * 1e6, S.player.t0), S.player.t1);
    S.settle = { t: Math.round(t), paused: q.get('paused') === '1', snapped: false };
    send({ op: 'seek', t: Math.round(t) });
  }
}

// The page has "settled" once it shows what its URL asked for (tests wait for this): the state
// of its own seek has come whole (a page opened at that time already had it, and would otherwise
// settle before the seek's snapshot clears and redraws what it shows).
function settledBy(player) {
  if (!S.settle) return true;
  return S.settle.snapped && Math.abs(player.t - S.settle.t) < 2000 && (!S.settle.paused || !player.playing);
}

// ---------------------------------------------------------------- messages

function handle(m) {
  switch (m.type) {
  case 'hello':
    S.mode = m.mode; S.controls = m.controls; S.channels = m.channels;
    body.dataset.mode = m.mode;
    body.dataset.state = 'ready';
    $('mode').textContent = m.mode === 'log' ? 'log' : 'live bus';
    $('controls').className = '';
    $('controls-info').textContent = m.controls ? 'controls enabled (signed orders)'
      : 'controls disabled (start with --key-file)';
    $('goal-mode').disabled = !m.controls;
    $('play').disabled = $('speed').disabled = m.mode !== 'log';
    break;
  case 'summary': onSummary(m); break;
  case 'player':
    S.player = m; S.now = m.t;
    $('play').textContent = m.playing ? '❚❚' : '▶';
    $('speed').value = String(m.speed);
    applyUrlOnce();
    if (settledBy(m)) S.settled = true;
    break;
  case 'snap':
    // the state at a new time follows: forget what belongs to another moment
    S.laser = S.particles = S.path = S.est = S.truth = null;
    S.decisions = []; S.comps = {};
    if (S.mode === 'live') { S.goals = {}; S.events = []; }
    S.now = m.t;
    break;
  case 'snapend':
    S.now = m.t;
    if (S.settle && Math.abs(m.t - S.settle.t) < 2000) S.settle.snapped = true;
    if (S.mode === 'live') S.settled = true;
    break;
  case 'trail':
    S.trail.est = m.est.map((p) => [p[1], p[2]]);
    S.trail.truth = m.truth.map((p) => [p[1], p[2]]);
    break;
  case 'msg': onMsg(m); break;
  case 'stats':
    S.rxAge = m.rx_age;
    if (S.mode === 'live') busBanner(m);
    break;
  case 'notice':
    notice(m.text);
    if (m.level === 'error') banner(m.text, 'error');
    controlPin.refused(m.text);
    break;
  case 'pong': break;
  }
}

function onSummary(m) {
  S.summary = m;
  $('source').textContent = m.file + ' — ' + ((m.t1 - m.t0) / 1e6).toFixed(1) + ' s, ' + m.records + ' records';
  body.dataset.corrupt = String(m.corrupt);
  if (m.records === 0) {
    banner('log has no readable records' + (m.corrupt ? ' (' + m.corrupt + ' corrupt stretches)' : ''), 'error');
  } else if (m.corrupt > 0) {
    const c = m.corrupt_list[0];
    banner('log has ' + m.corrupt + ' corrupt record' + (m.corrupt > 1 ? 's' : '') +
           ' (skipped; first at byte ' + c.off + ': ' + c.reason + ')', 'warn');
  } else if (m.bad_payloads > 0) {
    banner('log has ' + m.bad_payloads + ' undecodable messages (skipped)', 'warn');
  }
  body.dataset.decisions = String(m.dec.length);
  const legend = $('timeline-legend');
  legend.innerHTML = '';
  m.names.forEach((n) => {
    const s = document.createElement('span');
    s.innerHTML = '<span class="sw" style="background:' + colorOf(n) + '"></span>' + esc(n);
    legend.appendChild(s);
  });
}

// A message frame: f.k says what it is, f.msg is the message with the field names of its .lcm
// file (lcmtypes/), f.stride how much an array was thinned (docs/viewer.md, "Messages").
function onMsg(f) {
  const m = f.msg;
  if (f.t && f.t > S.now && S.mode === 'live') S.now = f.t;
  switch (f.k) {
  case 'map': setMap(m); break;
  case 'pose':
    if (f.role === 'truth') S.truth = m; else S.est = m;
    if (S.mode === 'live') {
      const tr = S.trail[f.role === 'truth' ? 'truth' : 'est'];
      const last = tr[tr.length - 1];
      if (!last || Math.hypot(last[0] - m.pose.x, last[1] - m.pose.y) > 0.05) tr.push([m.pose.x, m.pose.y]);
      if (tr.length > 5000) tr.splice(0, tr.length - 5000);
    }
    break;
  case 'laser':
    S.laser = m; S.laserStride = (f.stride && f.stride.ranges) || 1; S.counts.laser++;
    break;
  case 'particles': S.particles = m; body.dataset.particles = String(m.x.length); break;
  case 'path': S.path = m; body.dataset.path = String(m.poses.length); break;
  case 'goal':
    S.goals[m.id] = m; S.currentGoal = m.id;
    body.dataset.goals = String(Object.keys(S.goals).length);
    break;
  case 'arb':
    S.decisions.push(f);
    if (S.decisions.length > 200) S.decisions.splice(0, S.decisions.length - 200);
    if (S.mode === 'live') {
      S.liveDec.push([f.t, m.winner]);
      if (S.liveDec.length > 3000) S.liveDec.splice(0, S.liveDec.length - 3000);
      body.dataset.decisions = String(S.liveDec.length);
    }
    break;
  case 'event':
    if (S.mode === 'live') {
      S.events.push([f.t, m.source, m.severity, m.kind, m.text]);
      if (S.events.length > 500) S.events.shift();
    }
    break;
  case 'hb': {
    const old = S.comps[m.component];
    if (S.mode === 'live' && old && old.msg.pid !== m.pid) {
      S.restarts[m.component] = (S.restarts[m.component] || 0) + 1;
      S.events.push([f.t, m.component, 2, 'restart', 'restarted: pid ' + old.msg.pid + ' → ' + m.pid]);
    }
    S.comps[m.component] = f;
    noteOutputs(f);
    break;
  }
  case 'am': for (const c of m.components) S.am[c.name] = c; break;
  case 'reply': notice((m.ok ? 'order done on ' : 'order refused on ') + m.host + ': ' + m.reason); break;
  case 'tags': S.tags = m; break;
  case 'landmarks':
    S.landmarks = S.landmarks || {};
    for (const l of m.landmarks) S.landmarks[l.id] = l;
    body.dataset.landmarks = String(Object.keys(S.landmarks).length);
    break;
  }
}

// Live: what each component's output ports publish, from the counts in its heartbeats.
function noteOutputs(f) {
  const m = f.msg, t = f.t || 0;
  for (const p of m.ports || []) {
    if (p.direction !== 1) continue;
    const key = m.component + '/' + p.name, o = S.outs[key];
    if (o && t - o.t >= 500000) {
      S.outs[key] = { channel: p.channel, from: m.component, msgs: p.msgs, t, rate: Math.max(0, (p.msgs - o.msgs) / ((t - o.t) / 1e6)) };
    } else if (!o) {
      S.outs[key] = { channel: p.channel, from: m.component, msgs: p.msgs, t, rate: 0 };
    }
  }
}

// The channels this page draws (not the heartbeats and the managers' reports).
function drawnChannels() {
  const skip = ['heartbeat', 'am_status', 'am_reply', 'request', 'order'];
  return Object.entries(S.channels || {}).filter(([port]) => !skip.includes(port)).map(([, ch]) => ch);
}

// Live: the banner says what the bus carries. The server's rx_age is the age of the last message
// on a channel this page draws; the components' heartbeats say what else flows, so a bus busy
// with channels the page does not draw is reported as such, not as a silent one.
function busBanner(m) {
  // another banner (connection lost, a page error) stays until its own cause goes
  if ($('banner').className !== 'banner hidden' && $('banner').textContent !== S.busText) return;
  if (m.rx_age >= 0 && m.rx_age <= 3) {
    if (S.busText) banner('');
    S.busText = '';
    body.dataset.bus = 'drawn';
    return;
  }
  const flows = {};
  for (const o of Object.values(S.outs)) {
    if (o.rate < 0.5 || S.now - o.t > 3e6) continue;
    const f = flows[o.channel] || (flows[o.channel] = { rate: 0, from: [] });
    f.rate += o.rate; f.from.push(o.from);
  }
  const list = Object.entries(flows).sort((a, b) => b[1].rate - a[1].rate);
  let text, level = 'warn';
  if (list.length) {
    const total = list.reduce((n, e) => n + e[1].rate, 0);
    text = 'the bus carries ' + total.toFixed(0) + ' msg/s, ' + (m.rx_age < 0 ? 'none' : 'none for ' +
      m.rx_age.toFixed(0) + ' s') + ' on a channel this page draws: ' + list.slice(0, 3).map(([ch, f]) =>
      ch + ' ' + f.rate.toFixed(0) + '/s (' + f.from.join(', ') + ')').join(', ') + (list.length > 3 ? ', …' : '');
    level = 'info';
  } else if (m.rx_age < 0) {
    text = 'waiting for data from the bus…';
  } else {
    text = 'no data from the bus for ' + m.rx_age.toFixed(0) + ' s (heartbeats in the table)';
  }
  if (m.bad) text += '; ' + m.bad + ' messages refused (malformed, or not the type this page draws)';
  body.dataset.bus = level === 'info' ? 'other' : 'quiet';
  banner(text, level);
  $('banner').title = 'channels drawn here: ' + drawnChannels().join(', ');
  S.busText = text;
}

// An occupancy_grid_t: cells are base64 of int8 values, row 0 at the origin.
function setMap(m) {
  const w = m.width, h = m.height;
  if (!m.cells || w <= 0 || h <= 0) return;
  const raw = atob(m.cells);
  if (raw.length !== w * h) return;
  const c = document.createElement('canvas');
  c.width = w; c.height = h;
  const g = c.getContext('2d');
  const img = g.createImageData(w, h);
  for (let j = 0; j < h; j++) {
    for (let i = 0; i < w; i++) {
      let v = raw.charCodeAt(j * w + i);
      if (v > 127) v -= 256;
      const k = ((h - 1 - j) * w + i) * 4;   // row 0 is the bottom of the map
      const shade = v < 0 ? 205 : 255 - Math.round(Math.min(v, 100) * 2.2);
      img.data[k] = img.data[k + 1] = img.data[k + 2] = shade;
      img.data[k + 3] = 255;
    }
  }
  g.putImageData(img, 0, 0);
  S.map = m; S.mapCanvas = c;
  if (!S.view) fitView();
}

// ---------------------------------------------------------------- drawing

function fitView() {
  const cv = $('map');
  let x0, y0, x1, y1;
  if (S.map) {
    const m = S.map;
    x0 = m.origin.x; y0 = m.origin.y; x1 = x0 + m.width * m.resolution; y1 = y0 + m.height * m.resolution;
  } else {
    const p = (S.truth || S.est || {}).pose;
    if (!p) return;
    x0 = p.x - 10; x1 = p.x + 10; y0 = p.y - 7; y1 = p.y + 7;
  }
  const scale = Math.min(cv.width / (x1 - x0), cv.height / (y1 - y0)) * 0.98;
  S.view = { scale, cx: (x0 + x1) / 2, cy: (y0 + y1) / 2, auto: true };
}

// The map's drawing buffer follows its box, one canvas pixel per CSS pixel: the layout decides the
// map's size. A view fitted by the page is fitted again; one the user panned or zoomed stays.
function sizeMap() {
  const cv = $('map'), box = $('map-box');
  const w = Math.max(1, box.clientWidth), h = Math.max(1, box.clientHeight);
  if (cv.width === w && cv.height === h) return;
  cv.width = w; cv.height = h;
  if (S.view && S.view.auto) S.view = null;
  redraw();
}

function toPx(x, y) {
  const cv = $('map'), v = S.view;
  return [cv.width / 2 + (x - v.cx) * v.scale, cv.height / 2 - (y - v.cy) * v.scale];
}
function toWorld(px, py) {
  const cv = $('map'), v = S.view;
  return [v.cx + (px - cv.width / 2) / v.scale, v.cy - (py - cv.height / 2) / v.scale];
}

function redraw() {
  if (dirty) return;
  dirty = true;
  setTimeout(() => { dirty = false; try { draw(); } catch (e) { banner('page error: ' + e.message, 'error'); } }, 30);
}

function relMs(t) { return (t - (S.summary ? S.summary.t0 : 0)) / 1000; }

// Items of a summary list up to the current time (lists are sorted by time).
function upToNow(list) {
  const now = relMs(S.now);
  let lo = 0, hi = list.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (list[mid][0] <= now) lo = mid + 1; else hi = mid; }
  return lo;
}

function draw() {
  const cv = $('map'), g = cv.getContext('2d');
  g.setTransform(1, 0, 0, 1, 0, 0);
  g.fillStyle = '#e0e0e0';
  g.fillRect(0, 0, cv.width, cv.height);
  if (!S.view) fitView();
  if (S.view) {
    if (S.mapCanvas) {
      const m = S.map, [px, py] = toPx(m.origin.x, m.origin.y + m.height * m.resolution);
      g.imageSmoothingEnabled = false;
      g.drawImage(S.mapCanvas, px, py, m.width * m.resolution * S.view.scale, m.height * m.resolution * S.view.scale);
      body.dataset.mapDrawn = '1';
    }
    drawTrails(g);
    drawGoals(g);
    drawLandmarks(g);
    if (S.path) polyline(g, S.path.poses.map((p) => [p.x, p.y]), '#ff9800', 2.5);
    if (S.particles) {
      g.fillStyle = 'rgba(171,71,188,0.55)';
      for (let i = 0; i < S.particles.x.length; i++) {
        const [px, py] = toPx(S.particles.x[i], S.particles.y[i]);
        g.fillRect(px - 1, py - 1, 2, 2);
      }
    }
    drawLaser(g);
    // the page reports a pose or a scan once it is on the canvas, not when it arrives
    if (S.truth) { robot(g, S.truth.pose, '#2e7d32', null); body.dataset.truth = '1'; }
    if (S.est) { robot(g, S.est.pose, '#1565c0', S.est.cov); body.dataset.pose = '1'; }
    if (S.drag) {
      const [a, b] = [toPx(S.drag.x, S.drag.y), toPx(S.drag.x2, S.drag.y2)];
      g.strokeStyle = '#00838f'; g.lineWidth = 2;
      g.beginPath(); g.moveTo(a[0], a[1]); g.lineTo(b[0], b[1]); g.stroke();
    }
  } else {
    g.fillStyle = '#555'; g.font = '16px sans-serif';
    g.fillText(body.dataset.connected === '1' ? 'no map or pose yet' : 'not connected', 20, 30);
  }
  drawPanels();
  drawTimeline();
  body.dataset.settled = S.settled && body.dataset.connected === '1' ? '1' : '0';
}

function polyline(g, pts, color, width) {
  if (!pts || pts.length < 2) return;
  g.strokeStyle = color; g.lineWidth = width;
  g.beginPath();
  pts.forEach((p, i) => { const [x, y] = toPx(p[0], p[1]); if (i) g.lineTo(x, y); else g.moveTo(x, y); });
  g.stroke();
}

function drawTrails(g) {
  if (S.mode === 'log' && S.summary) {
    polyline(g, S.summary.truth.slice(0, upToNow(S.summary.truth)).map((p) => [p[1], p[2]]), 'rgba(46,125,50,0.7)', 1.5);
    polyline(g, S.summary.est.slice(0, upToNow(S.summary.est)).map((p) => [p[1], p[2]]), 'rgba(21,101,192,0.7)', 1.5);
  } else {
    polyline(g, S.trail.truth, 'rgba(46,125,50,0.7)', 1.5);
    polyline(g, S.trail.est, 'rgba(21,101,192,0.7)', 1.5);
  }
}

function goalList() {
  if (S.mode === 'log' && S.summary) {
    const seen = {};
    S.summary.goals.slice(0, upToNow(S.summary.goals)).forEach((gl) => { seen[gl[1]] = { id: gl[1], name: gl[2], pose: { x: gl[3], y: gl[4] } }; });
    Object.values(S.goals).forEach((gl) => { seen[gl.id] = gl; });
    return Object.values(seen);
  }
  return Object.values(S.goals);
}

function drawGoals(g) {
  const list = goalList();
  body.dataset.goals = String(list.length);
  g.font = '11px sans-serif';
  for (const gl of list) {
    const [x, y] = toPx(gl.pose.x, gl.pose.y);
    const cur = gl.id === S.currentGoal;
    g.strokeStyle = '#00838f'; g.fillStyle = cur ? 'rgba(0,131,143,0.35)' : 'rgba(0,131,143,0.1)';
    g.lineWidth = cur ? 2.5 : 1.2;
    g.beginPath(); g.arc(x, y, Math.max(5, (gl.tolerance || 0.3) * S.view.scale), 0, 2 * Math.PI); g.fill(); g.stroke();
    g.fillStyle = '#004d55'; g.fillText(gl.name || ('goal ' + gl.id), x + 8, y - 8);
  }
}

// Tags the robot placed in the map (marie-vision's landmarks): a square on the wall, a tick
// towards where the sign faces, and what it says.
function drawLandmarks(g) {
  if (!S.landmarks) return;
  g.font = '11px sans-serif';
  for (const l of Object.values(S.landmarks)) {
    const [x, y] = toPx(l.x, l.y), [fx, fy] = toPx(l.x + 0.4 * Math.cos(l.yaw), l.y + 0.4 * Math.sin(l.yaw));
    g.fillStyle = '#6a1b9a'; g.fillRect(x - 4, y - 4, 8, 8);
    g.strokeStyle = '#6a1b9a'; g.lineWidth = 1.5;
    g.beginPath(); g.moveTo(x, y); g.lineTo(fx, fy); g.stroke();
    g.fillText(l.message || ('tag ' + l.id), x + 6, y + 12);
  }
}

function drawLaser(g) {
  const l = S.laser, p = (S.truth || S.est || {}).pose;
  if (!l || !p) return;
  g.fillStyle = 'rgba(229,57,53,0.85)';
  const inc = l.angle_increment * S.laserStride;   // ranges[i] is beam i * stride
  for (let i = 0; i < l.ranges.length; i++) {
    const r = l.ranges[i];
    if (r === null || r >= l.range_max) continue;
    const a = p.theta + l.angle_min + i * inc;
    const [x, y] = toPx(p.x + r * Math.cos(a), p.y + r * Math.sin(a));
    g.fillRect(x - 1.5, y - 1.5, 3, 3);
  }
  body.dataset.laser = String(S.counts.laser);
}

// p: a pose2d_t; cov: its 3x3 covariance, row-major over x, y, theta
function robot(g, p, color, cov) {
  const [x, y] = toPx(p.x, p.y), r = Math.max(4, 0.25 * S.view.scale);
  if (cov) {
    const sx = Math.sqrt(Math.max(cov[0], 0)) * 2 * S.view.scale, sy = Math.sqrt(Math.max(cov[4], 0)) * 2 * S.view.scale;
    g.strokeStyle = 'rgba(21,101,192,0.6)'; g.lineWidth = 1;
    g.beginPath(); g.ellipse(x, y, Math.max(sx, 1), Math.max(sy, 1), 0, 0, 2 * Math.PI); g.stroke();
  }
  g.strokeStyle = color; g.lineWidth = 2.5;
  g.beginPath(); g.arc(x, y, r, 0, 2 * Math.PI); g.stroke();
  g.beginPath(); g.moveTo(x, y); g.lineTo(x + r * 1.6 * Math.cos(p.theta), y - r * 1.6 * Math.sin(p.theta)); g.stroke();
}

// ---------------------------------------------------------------- panels

const colors = {};
function colorOf(name) {
  if (!(name in colors)) colors[name] = PALETTE[Object.keys(colors).length % PALETTE.length];
  return colors[name];
}
// A speed or a rate as the panels show it: millimetres, and no trailing zeros.
// A message count in at most 4 characters (the table fits a laptop's side panel); exact in the title.
function count(n) {
  if (n < 10000) return String(n);
  if (n < 1e6) return (n / 1e3).toFixed(0) + 'k';
  if (n < 1e9) return (n / 1e6).toFixed(n < 1e7 ? 1 : 0) + 'M';
  return (n / 1e9).toFixed(1) + 'G';
}
function num(v) { return v === null ? '?' : +v.toFixed(3); }
function esc(s) {
  return String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c]));
}
function fmtT(t) {
  if (S.mode === 'log' && S.summary) return ((t - S.summary.t0) / 1e6).toFixed(1) + ' s';
  return new Date(t / 1000).toLocaleTimeString();
}

function drawPanels() {
  // time
  if (S.mode === 'log') {
    const p = S.player;
    $('time').textContent = ((p.t - p.t0) / 1e6).toFixed(1) + ' s / ' + ((p.t1 - p.t0) / 1e6).toFixed(1) + ' s';
  } else if (S.mode === 'live') {
    $('time').textContent = 'live';
  }
  $('clock').textContent = S.now ? fmtT(S.now) : '';

  // decisions: newest last in the data, newest first on the page
  const list = $('decision-list');
  // decisions are arbitration_t frames: their time t, the message msg
  const decs = S.decisions.filter((d) => S.mode !== 'log' || d.t <= S.now).slice(-30).reverse();
  list.innerHTML = '';
  decs.forEach((d, i) => {
    const a = d.msg, li = document.createElement('li');
    li.dataset.winner = a.winner;
    li.dataset.cycle = String(a.cycle);
    const vote = a.votes.find((v) => v.name === a.winner);
    li.innerHTML = '<span class="winner" style="background:' + colorOf(a.winner) + '">' + esc(a.winner) + '</span> ' +
      esc(fmtT(d.t)) + ' #' + a.cycle + '  v=' + num(a.v) + ' ω=' + num(a.omega) + (vote ? '  — ' + esc(vote.reason) : '');
    if (i === 0) li.className = 'current';
    if (decs[i + 1] && decs[i + 1].msg.winner !== a.winner) li.className += ' switch';
    li.onclick = () => { S.selected = d; redraw(); };
    list.appendChild(li);
  });
  $('decision-count').textContent = S.mode === 'log' && S.summary ? '(' + S.summary.dec.length + ' in the log)'
    : '(' + S.liveDec.length + ' received)';
  const cur = S.selected && (S.mode !== 'log' || S.selected.t <= S.now) ? S.selected : decs[0];
  const w = $('current-winner');
  if (cur) {
    const a = cur.msg;
    w.textContent = a.winner; w.style.background = colorOf(a.winner);
    let h = '<table><tr><th>behaviour</th><th>prio</th><th>active</th><th>v</th><th>ω</th><th>why</th></tr>';
    for (const v of a.votes) {
      h += '<tr class="' + (v.name === a.winner ? 'won' : '') + '"><td>' + esc(v.name) + '</td><td>' + v.priority + '</td><td class="' +
        (v.active ? 'active' : '') + '">' + (v.active ? 'yes' : 'no') + '</td><td>' + num(v.v) + '</td><td>' + num(v.omega) + '</td><td>' +
        esc(v.reason) + '</td></tr>';
    }
    h += '</table><div>inputs: ' + a.inputs.map((i) => esc(i.name) + ' ' + (i.age < 0 ? 'never' : (i.age * 1000).toFixed(0) + ' ms')).join(', ') +
      ' — cycle ' + a.cycle + ' at ' + esc(fmtT(cur.t)) + '</div>';
    $('decision-detail').innerHTML = h;
  }

  // components
  const tb = $('components').tBodies[0];
  const names = Object.keys(S.comps).concat(Object.keys(S.am).filter((n) => !(n in S.comps))).sort();
  const restartsLog = {};
  if (S.mode === 'log' && S.summary) S.summary.restarts.slice(0, upToNow(S.summary.restarts)).forEach((r) => { restartsLog[r[1]] = (restartsLog[r[1]] || 0) + 1; });
  tb.innerHTML = '';
  for (const n of names) {
    // c: the component's last heartbeat_t, seen at time t; a: its manager's am_component_status_t
    const f = S.comps[n], c = f ? f.msg : {}, a = S.am[n] || {};
    const rs = S.mode === 'log' ? (restartsLog[n] || 0) : Math.max(S.restarts[n] || 0, a.restarts || 0);
    const age = f && f.t ? (S.now - f.t) / 1e6 : null;
    const state = c.state !== undefined ? (STATES[c.state] || String(c.state)) : (a.state || '?');
    const tr = document.createElement('tr');
    tr.dataset.component = n;
    tr.dataset.restarts = String(rs);
    tr.className = (age !== null && age > 3 ? 'stale' : '') + (rs ? ' restarted' : '');
    tr.innerHTML = '<td>' + esc(n) + '</td><td>' + esc(c.host || '') + '</td><td class="state-' + esc(state) + '">' + esc(state) +
      (age !== null && age > 3 ? ' (silent ' + age.toFixed(0) + ' s)' : '') + '</td><td>' + (c.pid || a.pid || '') + '</td><td>' +
      (c.uptime_us !== undefined ? (c.uptime_us / 1e6).toFixed(0) + ' s' : '') + '</td><td class="restarts">' + rs + '</td><td>' +
      (c.msgs_in !== undefined ? '<span title="' + c.msgs_in + ' in, ' + c.msgs_out + ' out, ' + c.bad_input + ' bad input">' +
        count(c.msgs_in) + '/' + count(c.msgs_out) + '/' + count(c.bad_input) + '</span>' : '') + '</td><td>' +
      (a.cpu !== undefined ? a.cpu.toFixed(1) + '%' : '') +
      '</td><td></td>';
    if (S.controls) {
      const td = tr.lastChild;
      for (const [cmd, icon] of [['pause', '❚❚'], ['resume', '▶']]) {
        const b = document.createElement('button');
        b.textContent = icon;
        b.title = cmd + ' ' + n;
        b.onclick = () => send({ op: 'order', cmd, target: n, pin: controlPin.get() });
        td.appendChild(b);
      }
    }
    tb.appendChild(tr);
  }
  body.dataset.components = String(names.length);

  // fiducial tags of the last camera frame (camera frame: x right, z forward)
  if (S.tags) {
    $('tags-box').className = '';
    $('tags').textContent = S.tags.camera + ': ' + (S.tags.tags.length ? S.tags.tags.map((t) => '#' + t.id +
      (t.pose_valid ? ' at ' + t.position[2].toFixed(2) + ' m ahead, ' + t.position[0].toFixed(2) + ' m right' : '')).join('; ') : 'no tag in view');
  }

  // events
  const evs = S.mode === 'log' && S.summary ? S.summary.events.slice(0, upToNow(S.summary.events)).map((e) => [S.summary.t0 + e[0] * 1000, e[1], e[2], e[3], e[4]])
    : S.events;
  const rst = S.mode === 'log' && S.summary ? S.summary.restarts.slice(0, upToNow(S.summary.restarts))
    .map((r) => [S.summary.t0 + r[0] * 1000, r[1], 2, 'restart', 'restarted: pid ' + r[2] + ' → ' + r[3]]) : [];
  const all = evs.concat(rst).sort((a, b) => a[0] - b[0]).slice(-100).reverse();
  const ul = $('events');
  ul.innerHTML = '';
  for (const e of all) {
    const li = document.createElement('li');
    li.className = 'sev' + e[2] + ' ' + e[3];
    li.dataset.kind = e[3];
    li.textContent = fmtT(e[0]) + '  ' + e[1] + ': ' + e[3] + ' — ' + e[4];
    if (S.mode === 'log') {
      li.title = 'go there';
      li.onclick = () => send({ op: 'seek', t: e[0] });
    }
    ul.appendChild(li);
  }
  body.dataset.events = String(all.length);
}

// ---------------------------------------------------------------- timeline

function timeRange() {
  if (S.mode === 'log') return [S.player.t0, Math.max(S.player.t1, S.player.t0 + 1)];
  const end = S.now || Date.now() * 1000;
  return [end - 120e6, end];
}

function drawTimeline() {
  const cv = $('timeline');
  if (cv.width !== cv.clientWidth && cv.clientWidth > 0) cv.width = cv.clientWidth;
  const g = cv.getContext('2d'), W = cv.width, H = cv.height;
  g.clearRect(0, 0, W, H);
  const [a, b] = timeRange();
  const X = (t) => (t - a) / (b - a) * W;
  // decisions: one colour band per winner (a log's whole band is drawn once, then reused)
  if (S.mode === 'log' && S.summary) {
    if (!S.band || S.band.width !== W || S.bandOf !== S.summary) {
      S.band = document.createElement('canvas');
      S.band.width = W; S.band.height = H;
      S.bandOf = S.summary;
      drawBand(S.band.getContext('2d'), S.summary.dec.map((d) => [S.summary.t0 + d[0] * 1000, S.summary.names[d[1]]]), X, W);
    }
    g.drawImage(S.band, 0, 0);
  } else {
    drawBand(g, S.liveDec, X, W);
  }
  g.fillStyle = '#333'; g.font = '10px sans-serif';
  g.fillText('decisions', 2, 36);
  // events, goals reached, restarts
  const marks = [];
  if (S.mode === 'log' && S.summary) {
    S.summary.events.forEach((e) => marks.push([S.summary.t0 + e[0] * 1000, e[3] === 'goal_reached' ? '#2e7d32' : e[2] >= 2 ? '#c62828' : '#607d8b']));
    S.summary.restarts.forEach((r) => marks.push([S.summary.t0 + r[0] * 1000, '#ef6c00']));
  } else {
    S.events.forEach((e) => marks.push([e[0], e[3] === 'goal_reached' ? '#2e7d32' : e[2] >= 2 ? '#c62828' : '#607d8b']));
  }
  for (const [t, c] of marks) {
    const x = X(t);
    g.fillStyle = c;
    g.beginPath(); g.moveTo(x, 40); g.lineTo(x - 5, 58); g.lineTo(x + 5, 58); g.fill();
  }
  // cursor
  if (S.now) {
    const x = X(S.now);
    g.strokeStyle = '#000'; g.lineWidth = 2;
    g.beginPath(); g.moveTo(x, 0); g.lineTo(x, H); g.stroke();
  }
}

function drawBand(g, decs, X, W) {
  for (let i = 0; i < decs.length; i++) {
    const x0 = X(decs[i][0]), x1 = i + 1 < decs.length ? X(decs[i + 1][0]) : x0 + 2;
    if (x1 < 0 || x0 > W) continue;
    g.fillStyle = colorOf(decs[i][1]);
    g.fillRect(x0, 4, Math.max(1, x1 - x0), 22);
  }
}

// ---------------------------------------------------------------- input

$('play').onclick = () => send({ op: S.player.playing ? 'pause' : 'play' });
// space: play/pause; arrows: one second back or forward (logs)
window.addEventListener('keydown', (ev) => {
  if (S.mode !== 'log' || ev.target.tagName === 'SELECT') return;
  if (ev.key === ' ') { ev.preventDefault(); $('play').onclick(); }
  else if (ev.key === 'ArrowLeft' || ev.key === 'ArrowRight') {
    send({ op: 'seek', t: S.player.t + (ev.key === 'ArrowLeft' ? -1e6 : 1e6) });
  }
});
$('speed').onchange = () => send({ op: 'speed', v: Number($('speed').value) });

let scrubbing = false;
function seekAt(ev) {
  if (S.mode !== 'log') return;
  const cv = $('timeline'), r = cv.getBoundingClientRect();
  const [a, b] = timeRange();
  send({ op: 'seek', t: Math.round(a + (ev.clientX - r.left) / r.width * (b - a)) });
}
$('timeline').onmousedown = (ev) => { scrubbing = true; seekAt(ev); };
window.addEventListener('mousemove', (ev) => { if (scrubbing) seekAt(ev); });
window.addEventListener('mouseup', () => { scrubbing = false; });

$('goal-mode').onclick = () => {
  S.goalMode = !S.goalMode;
  $('goal-mode').textContent = S.goalMode ? 'Click the goal…' : 'Set goal';
};

const mapCv = $('map');
let pan = null;
function mapPos(ev) {
  const r = mapCv.getBoundingClientRect();
  return [(ev.clientX - r.left) * mapCv.width / r.width, (ev.clientY - r.top) * mapCv.height / r.height];
}
mapCv.onmousedown = (ev) => {
  if (!S.view) return;
  const [px, py] = mapPos(ev);
  if (S.goalMode) {
    const [x, y] = toWorld(px, py);
    S.drag = { x, y, x2: x, y2: y };
  } else {
    pan = { px, py, cx: S.view.cx, cy: S.view.cy };
  }
};
mapCv.onmousemove = (ev) => {
  const [px, py] = mapPos(ev);
  if (S.drag) { [S.drag.x2, S.drag.y2] = toWorld(px, py); redraw(); }
  else if (pan) {
    S.view.cx = pan.cx - (px - pan.px) / S.view.scale; S.view.cy = pan.cy + (py - pan.py) / S.view.scale;
    S.view.auto = false;
    redraw();
  }
};
mapCv.onmouseup = () => {
  if (S.drag) {
    const d = S.drag, len = Math.hypot(d.x2 - d.x, d.y2 - d.y);
    send({ op: 'goal', x: d.x, y: d.y, th: len > 0.2 ? Math.atan2(d.y2 - d.y, d.x2 - d.x) : 0, pin: controlPin.get() });
    S.drag = null; S.goalMode = false; $('goal-mode').textContent = 'Set goal';
  }
  pan = null;
  redraw();
};
mapCv.onwheel = (ev) => {
  if (!S.view) return;
  ev.preventDefault();
  S.view.scale *= ev.deltaY < 0 ? 1.15 : 1 / 1.15;
  S.view.auto = false;
  redraw();
};
mapCv.ondblclick = () => { S.view = null; redraw(); };

window.onerror = (msg) => { banner('page error: ' + msg, 'error'); };
new ResizeObserver(sizeMap).observe($('map-box'));
sizeMap();
connect();
redraw();
