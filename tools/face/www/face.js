// marie face: shows what the robot does and why, what it heard and said, and sends people's requests (with the PIN)
// to the server, which signs them. Reconnects when the server comes back.
"use strict";
const $ = (id) => document.getElementById(id);
let ws = null, places = [], currentGoal = "";
const words = { follow_path: "On my way", avoid: "Avoiding an obstacle", idle: "Waiting", estop: "Stopped (emergency stop)",
  teleop: "Driven by an operator" };

function notice(text, error) { const n = $("notice"); n.textContent = text; n.className = error ? "error" : ""; }

function send(obj) {
  if (!ws || ws.readyState !== 1) { notice("not connected", true); return; }
  obj.pin = $("pin").value;
  ws.send(JSON.stringify(obj));
}

function drawPlaces() {
  const box = $("places");
  box.textContent = "";
  places.forEach((name, i) => {
    const b = document.createElement("button");
    b.className = "place" + (name === currentGoal ? " current" : "");
    b.textContent = name;
    b.dataset.place = i;
    b.addEventListener("click", () => send({ op: "go", place: i }));
    box.appendChild(b);
  });
}

function host(m) {
  let el = document.querySelector('.host[data-host="' + CSS.escape(m.host) + '"]');
  if (!el) {
    el = document.createElement("div");
    el.className = "host";
    el.dataset.host = m.host;
    el.innerHTML = '<span class="light"></span><span></span>';
    el.lastChild.textContent = m.host;
    $("hosts").appendChild(el);
  }
  el.firstChild.className = "light " + m.light;
  el.dataset.seen = Date.now();
}

function event(m) {
  const d = document.createElement("div");
  d.textContent = m.text;
  const f = $("events");
  f.insertBefore(d, f.firstChild);
  while (f.children.length > 3) f.removeChild(f.lastChild);
}

// The conversation, newest last: the panel shows once the robot has heard or said something;
// the oldest lines go when the panel is full (at most 4).
function talk(m) {
  const d = document.createElement("div");
  d.className = "line " + m.who;
  d.dataset.who = m.who;
  const w = document.createElement("span");
  w.className = "words";
  w.textContent = m.text;
  d.appendChild(w);
  const t = $("talk");
  t.appendChild(d);
  t.hidden = false;
  while (t.children.length > 4 || (t.children.length > 1 && t.scrollHeight > t.clientHeight)) t.removeChild(t.firstChild);
}

function onMessage(m) {
  if (m.type === "hello") {  // the server replays the present after it
    $("events").textContent = "";
    $("talk").textContent = "";
    $("talk").hidden = true;
    places = m.places;
    drawPlaces();
    if (!m.controls) notice("requests are disabled on this robot", true);
  } else if (m.type === "arb") {
    $("what").textContent = words[m.winner] || m.winner;
    $("why").textContent = m.why + (currentGoal && m.winner === "follow_path" ? " — to " + currentGoal : "");
  } else if (m.type === "goal") {
    currentGoal = m.name;
    drawPlaces();
  } else if (m.type === "mission") {
    document.body.dataset.mission = m.done + "/" + m.goals;
    $("progress").textContent = "mission: " + m.done + " of " + m.goals + " goals done";
  } else if (m.type === "host") {
    host(m);
  } else if (m.type === "event") {
    event(m);
  } else if (m.type === "talk") {
    talk(m);
  } else if (m.type === "notice") {
    notice(m.text, m.level === "error");
  }
}

function connect() {
  ws = new WebSocket("ws://" + location.host + "/ws");
  ws.onopen = () => {
    document.body.dataset.conn = "1";
    notice("");
    $("what").textContent = "Ready";
    $("why").textContent = "no decision from the robot yet";
  };
  ws.onmessage = (e) => { try { onMessage(JSON.parse(e.data)); } catch (err) { /* one bad frame */ } };
  ws.onclose = () => {
    const b = document.body;
    if (b.dataset.conn === "1") b.dataset.drops = (+(b.dataset.drops || 0)) + 1;
    b.dataset.conn = "0";
    $("what").textContent = "No connection to the robot";
    if (b.dataset.drops) b.dataset.saidGone = "1";
    $("why").textContent = "trying again…";
    setTimeout(connect, 1000);
  };
}

$("stop").addEventListener("click", () => send({ op: "stop" }));
$("resume").addEventListener("click", () => send({ op: "resume" }));
// A host that stops reporting goes grey.
setInterval(() => {
  document.querySelectorAll(".host").forEach((el) => {
    if (Date.now() - el.dataset.seen > 3000) el.firstChild.className = "light gone";
  });
}, 1000);
connect();
