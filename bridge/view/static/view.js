// touchswarm live view: polls /state.json, draws the arena on a canvas with
// axes in patches, plots the behaviour's values over time, offers the
// scenario's parameters, and inspects a clicked robot.
// No framework, nothing fetched from elsewhere.
"use strict";

const POLL_MS = 200;
const MARGIN = {left: 36, bottom: 30, top: 6, right: 6};   // the arena's axes
const PLOT = {w: 376, h: 96, left: 44, right: 8, top: 18, bottom: 20};
const COLOURS = {object: "#ffd800", decoy: "#c8a2c8", obstacle: "#808080", home: "rgba(0,180,180,0.35)",
                 estimate: "#1040d0", claimed: "#000000",
                 guess: "rgba(40, 160, 60, 0.45)"};
const $ = (id) => document.getElementById(id);
let info = null;
// the page's state, readable from the tests and the bench (window.view)
const view = {st: null, zoom: 1, panX: 0, panY: 0, selected: null, drawn: 0, drawMs: 0};
window.view = view;

async function post(action, body) {
  const r = await fetch("/control/" + action, {
    method: "POST", headers: {"Content-Type": "application/json"},
    body: JSON.stringify(body || {})});
  const j = await r.json();
  $("error").textContent = r.ok ? "" : j.error;
  return {ok: r.ok, body: j};
}

function setupControls() {
  if (!info.controls) return;
  $("controls").hidden = false;
  $("play").onclick = () => post("play");
  $("pause").onclick = () => post("pause");
  $("step").onclick = () => post("step", {ticks: 1});
  $("speed").onchange = () => post("speed", {ticks_per_second: Number($("speed").value)});
}

// -- the parameters panel: the scenario's world keys and the behaviour's own --

function paramInput(p) {
  let el;
  if (p.kind === "choice") {
    el = document.createElement("select");
    for (const c of p.choices) {
      const o = document.createElement("option");
      o.value = o.textContent = c;
      el.appendChild(o);
    }
    el.value = p.value;
  } else if (p.kind === "bool") {
    el = document.createElement("input");
    el.type = "checkbox";
    el.checked = !!p.value;
  } else {
    el = document.createElement("input");
    el.type = "number";
    el.step = p.kind === "int" ? "1" : "any";
    if (p.low !== null && p.low !== undefined) el.min = p.low;
    if (p.high !== null && p.high !== undefined) el.max = p.high;
    el.value = p.value === null ? "" : p.value;
  }
  el.id = "param-" + p.name;
  el.dataset.name = p.name;
  return el;
}

function paramText(p, el) {
  // the value as `--set KEY=VALUE` reads it (TOML); null when unchanged
  if (p.kind === "bool") return el.checked === !!p.value ? null : String(el.checked);
  const v = el.value.trim();
  const now = p.value === null ? "" : String(p.value);
  if (v === now || (p.kind !== "choice" && v !== "" && Number(v) === Number(now))) return null;
  if (p.kind === "choice") return JSON.stringify(v);
  return v;
}

function setupParams() {
  if (!info.params) return;
  $("params").hidden = false;
  $("seed").value = info.seed;
  const list = $("param-list");
  list.innerHTML = "";
  let group = null;
  for (const p of info.params) {
    if (p.group !== group) {
      group = p.group;
      const h = document.createElement("h3");
      h.textContent = group;
      list.appendChild(h);
    }
    const label = document.createElement("label");
    const range = p.kind === "choice" ? "" : p.kind === "bool" ? "" :
      ` (${p.low ?? ""}..${p.high ?? ""})`;
    const name = document.createElement("span");
    name.textContent = p.name + range;
    label.title = p.meaning || "";
    label.appendChild(name);
    label.appendChild(paramInput(p));
    list.appendChild(label);
  }
  $("reset").onclick = reset;
}

async function reset() {
  const set = [];
  for (const p of info.params) {
    const t = paramText(p, $("param-" + p.name));
    if (t !== null) set.push(`${p.name}=${t}`);
  }
  const body = {set};
  if ($("seed").value !== "") body.seed = Number($("seed").value);
  const r = await post("reset", body);
  $("param-error").textContent = r.ok ? "" : r.body.error;
  if (r.ok) {
    view.selected = null;
    $("inspect").hidden = true;
    await loadInfo();
  }
}

// -- legends ------------------------------------------------------------------

function legendItem(colour, text, cls) {
  const s = document.createElement("span");
  const i = document.createElement("i");
  if (cls) i.className = cls;
  if (colour.startsWith("outline:")) {
    i.style.border = `2px solid ${colour.slice(8)}`;
    i.style.width = i.style.height = "7px";
  } else i.style.background = colour;
  s.appendChild(i);
  s.appendChild(document.createTextNode(text));
  return s;
}

function legends() {
  const st = $("state-legend");
  st.innerHTML = "robots by state: ";
  info.states.forEach((name, i) => st.appendChild(legendItem(info.colours[i], name, "dot")));
  const map = $("map-legend");
  map.innerHTML = "";
  // only what this run has: the server says what the behaviour and scenario declare
  const items = [[COLOURS.object, info.object ? (info.decoys ? "object (target)" : "object") : null],
                 [COLOURS.decoy, info.decoys ? "decoy" : null],
                 [COLOURS.obstacle, info.obstacles ? "obstacle" : null],
                 ["outline:" + COLOURS.estimate, info.shape ? "perceived (hull)" : null],
                 [COLOURS.guess, info.estimate ? "host's estimate" : null],
                 [COLOURS.home, info.home ? "home (radius 2)" : null],
                 ["outline:" + COLOURS.claimed,
                  info.source === "sim" && (info.object || info.decoys) ? "held cell" : null]];
  for (const [c, t] of items) if (t) map.appendChild(legendItem(c, t));
  map.appendChild(document.createTextNode("1 2 3: touches in order"));
  const scale = $("scale").getContext("2d");
  for (let x = 0; x < 160; x++) {
    scale.fillStyle = fieldColour(x / 159);
    scale.fillRect(x, 0, 1, 12);
  }
  $("field-legend").hidden = info.source !== "sim";
}

function fieldColour(f) { return `rgba(220,40,30,${0.1 + 0.6 * f})`; }

// -- the arena: patch (x, y) <-> canvas pixels, y upwards, zoom and pan ---------

function geometry(canvas) {
  const n = 2 * info.world + 1;
  const inner = Math.min(canvas.width - MARGIN.left - MARGIN.right,
                         canvas.height - MARGIN.top - MARGIN.bottom);
  const s = inner / n * view.zoom;
  const ox = MARGIN.left + view.panX, oy = MARGIN.top + view.panY;
  return {s, inner,
          px: (x) => ox + (x + info.world + 0.5) * s, py: (y) => oy + (info.world - y + 0.5) * s,
          ux: (p) => (p - ox) / s - info.world - 0.5, uy: (p) => info.world + 0.5 - (p - oy) / s};
}

function cells(ctx, g, list, colour) {
  ctx.fillStyle = colour;
  for (const [x, y] of list || []) ctx.fillRect(g.px(x) - g.s / 2, g.py(y) - g.s / 2, g.s, g.s);
}

function draw() {
  const st = view.st;
  if (!st || !info) return;
  const t0 = performance.now();
  const canvas = $("arena");
  const ctx = canvas.getContext("2d");
  const g = geometry(canvas);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.save();
  ctx.beginPath();
  ctx.rect(MARGIN.left, MARGIN.top, g.inner, g.inner);
  ctx.clip();
  $("scale-hi").textContent = st.field ? st.field.max : 0;
  if (st.field && st.field.max > 0) {           // the potential field, rows from y = -w
    const n = st.field.n;
    for (let r = 0; r < n; r++) for (let c = 0; c < n; c++) {
      const v = st.field.cells[r * n + c];
      if (!v) continue;
      ctx.fillStyle = fieldColour(v / st.field.max);
      ctx.fillRect(g.px(c - info.world) - g.s / 2, g.py(r - info.world) - g.s / 2, g.s, g.s);
    }
  }
  if (info.home) {
    ctx.fillStyle = COLOURS.home;
    ctx.beginPath();
    ctx.arc(g.px(info.home[0]), g.py(info.home[1]), 2 * g.s, 0, 2 * Math.PI);
    ctx.fill();
  }
  cells(ctx, g, st.obstacles, COLOURS.obstacle);
  cells(ctx, g, st.decoys, COLOURS.decoy);
  cells(ctx, g, st.object, COLOURS.object);
  ctx.strokeStyle = COLOURS.claimed;             // cells a robot holds
  ctx.lineWidth = 1;
  for (const [x, y] of st.claimed || []) ctx.strokeRect(g.px(x) - g.s / 2 + 0.5, g.py(y) - g.s / 2 + 0.5, g.s - 1, g.s - 1);
  ctx.fillStyle = COLOURS.guess;                 // the host's shape estimate, filled
  for (const [x, y] of st.estimate || []) ctx.fillRect(g.px(x) - g.s / 2 + 1, g.py(y) - g.s / 2 + 1, g.s - 2, g.s - 2);
  ctx.strokeStyle = COLOURS.estimate;            // the perceived shape
  ctx.lineWidth = 2;
  for (const [x, y] of st.perceived || []) ctx.strokeRect(g.px(x) - g.s / 2 + 2, g.py(y) - g.s / 2 + 2, g.s - 4, g.s - 4);
  const rad = Math.max(1.5, g.s * 0.42);
  ctx.lineWidth = 0.5;
  ctx.strokeStyle = "#000";
  for (let k = 0; k < info.colours.length; k++) {   // robots coloured by state, one path per state
    ctx.fillStyle = info.colours[k];
    ctx.beginPath();
    for (const r of st.robots || []) {
      if (r.state !== k) continue;
      ctx.moveTo(g.px(r.x) + rad, g.py(r.y));
      ctx.arc(g.px(r.x), g.py(r.y), rad, 0, 2 * Math.PI);
    }
    ctx.fill();
    if (rad > 3) ctx.stroke();
  }
  if (view.selected) {
    const r = (st.robots || []).find((q) => q.node === view.selected);
    if (r) {
      ctx.strokeStyle = "#ff00ff";
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(g.px(r.x), g.py(r.y), rad + 4, 0, 2 * Math.PI);
      ctx.stroke();
    }
  }
  ctx.font = `bold ${Math.max(10, Math.min(16, g.s * 0.8))}px sans-serif`;   // touches in order
  ctx.lineWidth = 3;
  ctx.strokeStyle = "#fff";
  ctx.fillStyle = "#000";
  const placed = [];
  for (const t of st.touches || []) {
    let x = g.px(t.sx) + g.s / 2, y = g.py(t.sy) - g.s / 2;
    while (placed.some(([a, b]) => Math.abs(a - x) < 12 && Math.abs(b - y) < 11)) y -= 11;
    placed.push([x, y]);
    ctx.strokeText(String(t.n), x, y);
    ctx.fillText(String(t.n), x, y);
  }
  ctx.restore();
  axes(ctx, g);
  view.drawn += 1;
  view.drawMs = performance.now() - t0;
}

function niceStep(span, pixels) {
  const want = span / Math.max(2, pixels / 60);
  for (const s of [1, 2, 5, 10, 20, 50, 100, 200, 500]) if (s >= want) return s;
  return 1000;
}

function axes(ctx, g) {
  ctx.strokeStyle = "#444";
  ctx.fillStyle = "#222";
  ctx.lineWidth = 1;
  ctx.strokeRect(MARGIN.left, MARGIN.top, g.inner, g.inner);
  ctx.font = "11px sans-serif";
  const x0 = g.ux(MARGIN.left), x1 = g.ux(MARGIN.left + g.inner);
  const y1 = g.uy(MARGIN.top), y0 = g.uy(MARGIN.top + g.inner);
  const step = niceStep(x1 - x0, g.inner);
  ctx.textAlign = "center";
  for (let v = Math.ceil(x0 / step) * step; v <= x1; v += step) {
    const p = g.px(v);
    ctx.beginPath(); ctx.moveTo(p, MARGIN.top + g.inner); ctx.lineTo(p, MARGIN.top + g.inner + 4); ctx.stroke();
    ctx.fillText(String(v), p, MARGIN.top + g.inner + 14);
  }
  ctx.fillText("x (patches)", MARGIN.left + g.inner / 2, MARGIN.top + g.inner + 27);
  ctx.textAlign = "right";
  for (let v = Math.ceil(y0 / step) * step; v <= y1; v += step) {
    const p = g.py(v);
    ctx.beginPath(); ctx.moveTo(MARGIN.left - 4, p); ctx.lineTo(MARGIN.left, p); ctx.stroke();
    ctx.fillText(String(v), MARGIN.left - 6, p + 4);
  }
  ctx.save();
  ctx.translate(10, MARGIN.top + g.inner / 2);
  ctx.rotate(-Math.PI / 2);
  ctx.textAlign = "center";
  ctx.fillText("y (patches)", 0, 0);
  ctx.restore();
  ctx.textAlign = "left";
}

let pending = false;
function redraw() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => { pending = false; draw(); });
}

// zoom (wheel, about the cursor), pan (drag), whole arena (double-click),
// inspect (click on a robot), claimed-by (hover over a cell)
function setupArena() {
  const canvas = $("arena");
  let drag = null;
  canvas.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    const f = ev.deltaY < 0 ? 1.25 : 0.8;
    const z = Math.min(40, Math.max(1, view.zoom * f));
    const mx = ev.offsetX - MARGIN.left, my = ev.offsetY - MARGIN.top;
    view.panX = mx - (mx - view.panX) * z / view.zoom;
    view.panY = my - (my - view.panY) * z / view.zoom;
    view.zoom = z;
    if (z === 1) view.panX = view.panY = 0;
    redraw();
  }, {passive: false});
  canvas.addEventListener("mousedown", (ev) => { drag = {x: ev.offsetX, y: ev.offsetY, moved: false}; });
  canvas.addEventListener("mousemove", (ev) => {
    if (drag && ev.buttons) {
      const dx = ev.offsetX - drag.x, dy = ev.offsetY - drag.y;
      if (Math.abs(dx) + Math.abs(dy) > 2) drag.moved = true;
      if (drag.moved) {
        view.panX += dx; view.panY += dy;
        drag.x = ev.offsetX; drag.y = ev.offsetY;
        redraw();
      }
    }
    hover(ev.offsetX, ev.offsetY);
  });
  canvas.addEventListener("mouseup", (ev) => {
    if (drag && !drag.moved) pick(ev.offsetX, ev.offsetY);
    drag = null;
  });
  canvas.addEventListener("dblclick", () => { view.zoom = 1; view.panX = view.panY = 0; redraw(); });
}

function hover(cx, cy) {
  const st = view.st;
  if (!st) return;
  const g = geometry($("arena"));
  const x = Math.round(g.ux(cx)), y = Math.round(g.uy(cy));
  let text = `patch (${x}, ${y})`;
  const held = (st.claimed || []).find(([a, b]) => a === x && b === y);
  const onObject = (st.object || []).some(([a, b]) => a === x && b === y);
  if (held) text += `: object cell held by robot ${held[2]}`;
  else if (onObject) text += ": object cell, held by no robot";
  if (st.field && st.field.max > 0 && Math.abs(x) <= info.world && Math.abs(y) <= info.world)
    text += ` · field ${st.field.cells[(y + info.world) * st.field.n + x + info.world]}`;
  $("hover").textContent = text;
}

async function pick(cx, cy) {
  const st = view.st;
  if (!st) return;
  const g = geometry($("arena"));
  let best = null, bestD = Math.max(8, g.s);
  for (const r of st.robots || []) {
    const d = Math.hypot(g.px(r.x) - cx, g.py(r.y) - cy);
    if (d <= bestD) { best = r; bestD = d; }
  }
  if (!best) return;
  view.selected = best.node;
  redraw();
  await inspect();
}

async function inspect() {
  if (view.selected === null) return;
  const sec = $("inspect");
  sec.hidden = false;
  $("insp-node").textContent = view.selected;
  if (!info.controls) {               // a host knows only the last HEARTBEAT
    const r = (view.st.robots || []).find((q) => q.node === view.selected);
    if (!r) return;
    $("insp-state").textContent = info.states[r.state] + (r.halted ? " (host sent HALT)" : "");
    $("insp-vars").innerHTML = `<div>pose <b>(${r.x}, ${r.y})</b></div>` +
      `<div>heard at tick <b>${r.heard_tick}</b></div>`;
    $("insp-msgs").innerHTML = "";
    return;
  }
  const resp = await fetch("/robot.json?node=" + view.selected);
  const r = await resp.json();
  if (!resp.ok) { $("error").textContent = r.error; return; }
  $("insp-state").textContent = r.state;
  const rows = [["tick", r.tick], ["pose", `(${r.x.toFixed(2)}, ${r.y.toFixed(2)})`],
                ["heading", r.heading === null ? "-" : r.heading + "°"],
                ...Object.entries(r.variables)];
  $("insp-vars").innerHTML = rows.map(([k, v]) => `<div>${k} <b id="insp-${k}">${v}</b></div>`).join("");
  $("insp-msgs").innerHTML = r.messages.map((m) => `<li>tick ${m.tick} ${m.way}: ${m.text}</li>`).join("");
}

// -- plots over time: one per panel the server lists (the behaviour's words) -----

function setupPlots() {
  const box = $("plots");
  box.innerHTML = "";
  for (const p of info.plots || []) {
    const c = document.createElement("canvas");
    c.id = "plot-" + p.id;
    c.width = PLOT.w; c.height = PLOT.h;
    c.className = "plot";
    box.appendChild(c);
    const last = document.createElement("div");
    last.id = "last-" + p.id;
    last.className = "plot-last";
    box.appendChild(last);
  }
}

function fmt(v) {
  if (v === null || v === undefined) return "-";
  return Number.isInteger(v) ? String(v) : v.toFixed(2);
}

function plots(cols) {
  if (!cols || !info.plots) return;
  const ticks = cols.tick;
  for (const p of info.plots) {
    const c = $("plot-" + p.id);
    if (!c) continue;
    const ctx = c.getContext("2d");
    ctx.clearRect(0, 0, c.width, c.height);
    const w = PLOT.w - PLOT.left - PLOT.right, h = PLOT.h - PLOT.top - PLOT.bottom;
    let lo = 0, hi = 1;
    if (p.range) [lo, hi] = p.range;
    else for (const s of p.series) for (const v of cols[s.key] || []) {
      if (v === null) continue;
      if (v > hi) hi = v;
      if (v < lo) lo = v;
    }
    const t0 = ticks.length ? ticks[0] : 0, t1 = ticks.length ? Math.max(ticks[ticks.length - 1], t0 + 1) : 1;
    const X = (t) => PLOT.left + (t - t0) / (t1 - t0) * w;
    const Y = (v) => PLOT.top + h - (v - lo) / (hi - lo) * h;
    ctx.strokeStyle = "#888";
    ctx.lineWidth = 1;
    ctx.strokeRect(PLOT.left, PLOT.top, w, h);
    ctx.fillStyle = "#222";
    ctx.font = "bold 11px sans-serif";
    let title = `${p.title} (${p.unit})`;             // cut to the plot's width
    while (title.length > 8 && ctx.measureText(title).width > PLOT.w - 4) title = title.slice(0, -2) + "…";
    ctx.fillText(title, 2, 12);
    c.title = `${p.title} (${p.unit})`;
    ctx.font = "10px sans-serif";
    ctx.textAlign = "right";
    ctx.fillText(fmt(hi), PLOT.left - 3, PLOT.top + 8);
    ctx.fillText(fmt(lo), PLOT.left - 3, PLOT.top + h);
    ctx.textAlign = "left";
    ctx.fillText(`tick ${t0}`, PLOT.left, PLOT.h - 6);
    ctx.textAlign = "right";
    ctx.fillText(`tick ${ticks.length ? ticks[ticks.length - 1] : 0}`, PLOT.left + w, PLOT.h - 6);
    ctx.textAlign = "left";
    const last = {};
    for (const s of p.series) {
      const ys = cols[s.key] || [];
      ctx.strokeStyle = s.colour;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      let on = false;
      for (let i = 0; i < ys.length; i++) {
        if (ys[i] === null) { on = false; continue; }
        if (on) ctx.lineTo(X(ticks[i]), Y(ys[i])); else ctx.moveTo(X(ticks[i]), Y(ys[i]));
        on = true;
      }
      ctx.stroke();
      last[s.key] = ys.length ? ys[ys.length - 1] : null;
    }
    c.dataset.last = JSON.stringify(last);
    c.dataset.tick = ticks.length ? ticks[ticks.length - 1] : 0;
    const box = $("last-" + p.id);
    const html = p.series.map((s) => `<span style="color:${s.colour}">&#9632;</span> ${s.label} ` +
                                     `<b>${fmt(last[s.key])}</b>`).join(" &middot; ");
    if (box.innerHTML !== html) box.innerHTML = html;
  }
}

// -- the side panel ---------------------------------------------------------------

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
  $("playing").textContent = info.controls ? (st.finished ? "finished" : st.playing ? "running" : "paused")
                                           : (st.live ? "following the host" : "no poses journalled yet");
  $("status").textContent = st.status || "";
  if (st.error) $("error").textContent = st.error;
  const touches = st.touches || [];
  $("touch-count").textContent = touches.length;
  const ol = $("touches");
  while (ol.children.length > touches.length) ol.removeChild(ol.lastChild);
  for (let i = 0; i < touches.length; i++) {
    const t = touches[i];
    const text = `robot ${t.node} at tick ${t.tick}, segment (${t.sx}, ${t.sy})`;
    if (i < ol.children.length) {
      if (ol.children[i].textContent !== text) ol.children[i].textContent = text;
      continue;
    }
    const li = document.createElement("li");
    li.className = "touch";
    li.textContent = text;
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
    if (r.ok) {
      view.st = st;
      draw();
      plots(st.plots);
      panel(st);
      if (view.selected !== null && !$("inspect").hidden) await inspect();
    } else $("error").textContent = st.error;
  } catch (e) {
    $("error").textContent = "server gone: " + e;
  }
  setTimeout(poll, POLL_MS);
}

async function loadInfo() {
  info = await (await fetch("/info.json")).json();
  $("title").textContent = info.title;
  legends();
  setupPlots();
  setupParams();
  if (info.load) {
    $("load").hidden = false;
    $("held-word").textContent = info.load[0];
    $("need-word").textContent = info.load[1];
  }
}

async function start() {
  await loadInfo();
  setupControls();
  setupArena();
  poll();
}

start();
