// touchswarm live view: polls /state.json and draws the arena on a canvas.
// No framework, nothing fetched from elsewhere.
"use strict";

const POLL_MS = 200;
const $ = (id) => document.getElementById(id);
let info = null;

async function post(action, body) {
  const r = await fetch("/control/" + action, {
    method: "POST", headers: {"Content-Type": "application/json"},
    body: JSON.stringify(body || {})});
  const j = await r.json();
  $("error").textContent = r.ok ? "" : j.error;
}

function setupControls() {
  if (!info.controls) return;
  $("controls").hidden = false;
  $("play").onclick = () => post("play");
  $("pause").onclick = () => post("pause");
  $("step").onclick = () => post("step", {ticks: 1});
  $("speed").onchange = () => post("speed", {ticks_per_second: Number($("speed").value)});
}

function legend() {
  $("legend").innerHTML = "";
  info.states.forEach((name, i) => {
    const s = document.createElement("span");
    s.innerHTML = `<i style="background:${info.colours[i]}"></i>${name}`;
    $("legend").appendChild(s);
  });
}

// patch (x, y) -> canvas pixels; y grows upwards as in the figures
function geometry(canvas) {
  const n = 2 * info.world + 1;
  const s = canvas.width / n;
  return {s, px: (x) => (x + info.world) * s, py: (y) => (info.world - y) * s};
}

function draw(st) {
  const canvas = $("arena");
  const ctx = canvas.getContext("2d");
  const g = geometry(canvas);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  if (st.field && st.field.max > 0) {           // the potential field, rows from y = -w
    const n = st.field.n;
    for (let r = 0; r < n; r++) for (let c = 0; c < n; c++) {
      const v = st.field.cells[r * n + c];
      if (!v) continue;
      ctx.fillStyle = `rgba(220,40,30,${0.1 + 0.6 * v / st.field.max})`;
      ctx.fillRect(g.px(c - info.world) - g.s / 2, g.py(r - info.world) - g.s / 2, g.s, g.s);
    }
  }
  ctx.fillStyle = "rgba(0,180,180,0.35)";        // home
  ctx.beginPath();
  ctx.arc(g.px(info.home[0]), g.py(info.home[1]), 2 * g.s, 0, 2 * Math.PI);
  ctx.fill();
  ctx.fillStyle = "#ffd800";                     // the object's cells
  for (const [x, y] of st.object || []) ctx.fillRect(g.px(x) - g.s / 2, g.py(y) - g.s / 2, g.s, g.s);
  ctx.strokeStyle = "#1040d0";                   // the perceived shape
  ctx.lineWidth = 2;
  for (const [x, y] of st.perceived || []) ctx.strokeRect(g.px(x) - g.s / 2 + 1, g.py(y) - g.s / 2 + 1, g.s - 2, g.s - 2);
  for (const r of st.robots || []) {             // robots coloured by state
    ctx.fillStyle = info.colours[r.state] || "#000";
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 0.5;
    ctx.beginPath();
    ctx.arc(g.px(r.x), g.py(r.y), Math.max(2, g.s * 0.45), 0, 2 * Math.PI);
    ctx.fill();
    ctx.stroke();
  }
  ctx.fillStyle = "#000";                        // touches numbered in order
  ctx.font = `bold ${Math.max(10, g.s)}px sans-serif`;
  for (const t of st.touches || []) ctx.fillText(String(t.n), g.px(t.sx) + g.s / 2, g.py(t.sy) - g.s / 2);
}

// the behaviour's measures and reporters, each with its title
function measures(rows) {
  const table = $("measures");
  const html = rows.map((m) => `<tr><td class="value" id="m-${m.name}">${valueText(m)}</td>` +
                               `<td>${m.title}</td></tr>`).join("");
  if (table.innerHTML !== html) table.innerHTML = html;
}

function valueText(m) {
  if (m.value === null || m.value === undefined) return m.name.endsWith("_tick") ? "never" : "-";
  if (m.name.endsWith("_tick")) return "tick " + m.value;
  if (Array.isArray(m.value)) return String(m.value.length);
  return String(m.value);
}

function panel(st) {
  $("tick").textContent = st.tick;
  $("playing").textContent = info.controls ? (st.finished ? "finished" : st.playing ? "playing" : "paused")
                                           : (st.live ? "following the host" : "no poses journalled yet");
  $("status").textContent = st.status || "";
  if (st.error) $("error").textContent = st.error;
  const touches = st.touches || [];
  $("touch-count").textContent = touches.length;
  const ol = $("touches");
  while (ol.children.length > touches.length) ol.removeChild(ol.lastChild);
  for (let i = ol.children.length; i < touches.length; i++) {
    const t = touches[i];
    const li = document.createElement("li");
    li.className = "touch";
    li.textContent = `robot ${t.node} at tick ${t.tick}, segment (${t.sx}, ${t.sy})`;
    ol.appendChild(li);
  }
  if (info.load) {                               // the behaviour's load, e.g. power of weight
    const held = st[info.load[0]] || 0, need = st[info.load[1]] || 0;
    $("held").textContent = held.toFixed(2);
    $("need").textContent = need.toFixed(2);
    const full = Math.max(held, need, 1e-9) * 1.25;
    $("held-fill").style.width = (100 * held / full) + "%";
    $("need-mark").style.left = (100 * need / full) + "%";
  }
  measures(st.measures || []);
  const bad = st.bad_frames || {};
  const total = Object.values(bad).reduce((a, b) => a + b, 0);
  $("bad-frames").textContent = total + (total ? " (" + Object.entries(bad).map(([k, v]) => `${k} ${v}`).join(", ") + ")" : "");
  const ev = $("events");
  const text = (st.events || []).join("\n");
  if (ev.textContent !== text) { ev.textContent = text; ev.scrollTop = ev.scrollHeight; }
  document.body.dataset.tick = st.tick;
}

async function poll() {
  try {
    const r = await fetch("/state.json");
    const st = await r.json();
    if (r.ok) { draw(st); panel(st); } else $("error").textContent = st.error;
  } catch (e) {
    $("error").textContent = "server gone: " + e;
  }
  setTimeout(poll, POLL_MS);
}

async function start() {
  info = await (await fetch("/info.json")).json();
  $("title").textContent = info.title;
  setupControls();
  legend();
  if (info.load) {
    $("load").hidden = false;
    $("held-word").textContent = info.load[0];
    $("need-word").textContent = info.load[1];
  }
  poll();
}

start();
