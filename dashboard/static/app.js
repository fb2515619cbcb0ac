// The WNCS dashboard page: records arrive by stream over the WebSocket (dashboard/view.py says
// what each stream holds); everything is drawn "as of" a cursor time, which follows the run
// while it is live and the slider otherwise, so a live run and a replay are the same page.
"use strict";

const store = {};          // stream name -> records, in time order
let info = null;           // the run's static description (hello)
let runId = null;
let live = false;
let finished = null;       // the clock's stop message, once the run has ended
let latest = 0;            // simulated time of the newest record
let follow = true;
let cursor = 0;
let playing = null;
let nextId = 1;
let dirty = true;
const sent = {};           // request id -> its <li>
const charts = {};         // loop -> {out, period}
let delayChart = null, clockChart = null, cy = null, cyNet = null;
let timelineShown = -1, scheduleShown = null;

const $ = (id) => document.getElementById(id);
const tOf = (r) => (Array.isArray(r) ? r[0] : r.t);
const fmt = (v, d = 4) => (v === null || v === undefined ? "–" : Number(v).toPrecision(d));

function upto(name, t) {   // the records of a stream up to time t
  const recs = store[name] || [];
  let lo = 0, hi = recs.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (tOf(recs[mid]) <= t) lo = mid + 1; else hi = mid; }
  return recs.slice(0, lo);
}
function lastAt(name, t) { const r = upto(name, t); return r.length ? r[r.length - 1] : null; }
function streams(prefix) { return Object.keys(store).filter((k) => k.startsWith(prefix)).sort(); }

// -- the socket ----------------------------------------------------------------------------------
const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
ws.onmessage = (ev) => {
  const msg = JSON.parse(ev.data);
  if (msg.type === "hello") { hello(msg); }
  else if (msg.type === "data") {
    for (const [name, recs] of Object.entries(msg.append)) (store[name] = store[name] || []).push(...recs);
    latest = Math.max(latest, msg.t);
  } else if (msg.type === "finished") { finished = msg.stop; live = false; }
  else if (msg.type === "ack" || msg.type === "error") { answer(msg); }
  dirty = true;
};
ws.onclose = () => { if (!finished) setStatus("disconnected", "lost"); };

function send(request, summary) {
  const id = nextId++;
  const li = document.createElement("li");
  li.textContent = `#${id} ${summary}: sent`;
  $("messages").prepend(li);
  sent[id] = li;
  ws.send(JSON.stringify({ id, ...request }));
}
function answer(msg) {
  const li = sent[msg.id] || document.createElement("li");
  if (!sent[msg.id]) $("messages").prepend(li);
  li.className = msg.type;
  li.textContent = msg.type === "ack"
    ? `#${msg.id} ${msg.summary}: accepted by the clock's inbox, stamped into the next round`
    : `${msg.id ? "#" + msg.id + " " : ""}refused: ${msg.reason}`;
}

// -- set-up from the run's description -----------------------------------------------------------
function hello(msg) {
  info = msg.static; runId = msg.run_id; live = msg.live;
  $("title").textContent = `${info.name} · ${runId || ""}`;
  document.querySelectorAll(".unit").forEach((e) => (e.textContent = info.time_unit));
  $("slider").max = info.end;
  for (const m of info.modes) $("mode").add(new Option(m, m));
  for (const [name, lp] of Object.entries(info.loops)) {
    if (lp.setpoint !== null) $("sp-loop").add(new Option(name, name));
    addLoop(name, lp);
  }
  const spNow = () => { const r = lastAt(`sp/${$("sp-loop").value}`, latest); $("sp-value").value = r ? r[1] : ""; };
  $("sp-loop").addEventListener("change", spNow); setTimeout(spNow, 500);
  const nets = Object.keys(info.networks);
  cyNet = nets.length ? nets[0] : null;
  $("net-name").textContent = cyNet ? `(${cyNet})` : "(wired)";
  $("interference-row").hidden = !(cyNet && info.networks[cyNet].tsch);
  delayChart = new uPlot(chartOpts("delay", [], 280), [[]], $("delay-chart"));
  clockChart = new uPlot({
    width: chartWidth(), height: 160,
    scales: { x: { time: false } },
    axes: [{ label: "wall, s" }, { label: `simulated, ${info.time_unit}` }],
    series: [{}, { label: "t", stroke: "#1565c0" }],
  }, [[], []], $("clock-chart"));
}

function chartWidth() { return Math.max(420, $("loops").clientWidth - 20); }

function chartOpts(kind, series, height) {
  return {
    width: chartWidth(), height,
    scales: { x: { time: false } },
    axes: [{ label: info.time_unit }, { label: kind }],
    series: [{}, ...series],
  };
}

function addLoop(name, lp) {
  const card = document.createElement("section");
  card.className = "card loop"; card.id = `loop-${name}`; card.dataset.points = "0";
  card.innerHTML = `<h2>${name} <span>${lp.plant}.${lp.sensor || "–"} ← ${lp.actuator || "–"}</span></h2>
    <div class="out"></div><div class="period"></div>`;
  $("loops").append(card);
  const out = new uPlot({
    width: chartWidth(), height: 220,
    scales: { x: { time: false }, u: {} },
    axes: [{ label: info.time_unit }, { label: lp.sensor || "output" },
           { scale: "u", side: 1, label: lp.actuator || "u", grid: { show: false } }],
    series: [{},
      { label: "output", stroke: "#1565c0", width: 1.5, spanGaps: true },
      { label: "set point", stroke: "#000", dash: [6, 4], spanGaps: true, paths: uPlot.paths.stepped({ align: 1 }) },
      { label: "delivered samples", stroke: "#2e7d32", paths: () => null, points: { show: true, size: 4 } },
      { label: "move", stroke: "#ef6c00", scale: "u", spanGaps: true, paths: uPlot.paths.stepped({ align: 1 }) }],
  }, [[], [], [], [], []], card.querySelector(".out"));
  const period = new uPlot({
    width: chartWidth(), height: 110,
    scales: { x: { time: false } },
    axes: [{ label: info.time_unit }, { label: `τs, ${info.time_unit}` }],
    series: [{}, { label: "sampling period (shaded: loop open)", stroke: "#6a1b9a", spanGaps: true,
                   paths: uPlot.paths.stepped({ align: 1 }) }],
    hooks: { drawClear: [(u) => shadeOpen(u, name)] },
  }, [[], []], card.querySelector(".period"));
  charts[name] = { out, period, card };
}

function shadeOpen(u, loop) {   // the intervals in which the loop ran open
  const recs = upto(`period/${loop}`, cursor);
  const ctx = u.ctx;
  ctx.save(); ctx.fillStyle = "rgba(255,152,0,0.18)";
  recs.forEach((r, i) => {
    if (r[2]) return;
    const t1 = i + 1 < recs.length ? recs[i + 1][0] : cursor;
    const x0 = u.valToPos(r[0], "x", true), x1 = u.valToPos(t1, "x", true);
    ctx.fillRect(x0, u.bbox.top, Math.max(1, x1 - x0), u.bbox.height);
  });
  ctx.restore();
}

// -- drawing as of the cursor --------------------------------------------------------------------
function columns(recs) { return [recs.map((r) => r[0]), recs.map((r) => r[1])]; }

function drawLoops() {
  for (const [name, c] of Object.entries(charts)) {
    const y = upto(`y/${name}`, cursor), meas = upto(`meas/${name}`, cursor);
    const sp = upto(`sp/${name}`, cursor), u = upto(`u/${name}`, cursor);
    if (sp.length) sp.push([cursor, sp[sp.length - 1][1]]);
    if (u.length) u.push([cursor, u[u.length - 1][1]]);
    c.out.setData(uPlot.join([columns(y), columns(sp), columns(meas), columns(u)]));
    c.card.dataset.points = String(y.length + meas.length);
    const per = upto(`period/${name}`, cursor).map((r) => [r[0], r[1]]);
    if (per.length) per.push([cursor, per[per.length - 1][1]]);
    c.period.setData(per.length ? columns(per) : [[], []]);
  }
}

function drawDelays() {
  const names = streams("delay/");
  if (delayChart.series.length - 1 !== names.length) {
    delayChart.destroy();
    const colors = ["#1565c0", "#c62828", "#2e7d32", "#6a1b9a", "#ef6c00", "#00838f"];
    delayChart = new uPlot(chartOpts(`delay, ${info.time_unit}`, names.map((n, i) => ({
      label: n.slice(6), stroke: colors[i % colors.length], paths: () => null,
      points: { show: true, size: 3, fill: colors[i % colors.length] } })), 200), [[], ...names.map(() => [])],
      $("delay-chart"));
  }
  if (!names.length) return;
  delayChart.setData(uPlot.join(names.map((n) => columns(upto(n, cursor)))));
}

function drawClock() {
  const recs = (store.clock || []).filter((r) => r[1] <= cursor);
  $("clock-card").hidden = !(store.clock || []).length;
  clockChart.setData(columns(recs));
  if (recs.length > 1) {
    const a = recs[0], b = recs[recs.length - 1];
    $("rate").textContent = b[0] > a[0] ? `${((b[1] - a[1]) / (b[0] - a[0])).toFixed(2)} ${info.time_unit}/s` : "";
  }
}

function drawTopology() {
  if (!cyNet) return;
  const topo = lastAt(`topology/${cyNet}`, cursor);
  if (!topo) return;
  const routes = (lastAt(`routes/${cyNet}`, cursor) || { routes: {} }).routes;
  const onRoute = new Set();
  for (const route of Object.values(routes)) for (let i = 0; i + 1 < route.length; i++) onRoute.add([route[i], route[i + 1]].sort().join("|"));
  const pos = info.networks[cyNet].positions;
  if (!cy) {
    cy = cytoscape({
      container: $("topology"),
      style: [
        { selector: "node", style: { label: "data(id)", "background-color": "data(color)", "font-size": 10, width: 22, height: 22 } },
        { selector: "node[kind = 'gateway']", style: { shape: "diamond", width: 28, height: 28 } },
        { selector: "node[kind = 'sensor']", style: { shape: "triangle" } },
        { selector: "node.down", style: { "background-color": "#9e9e9e", "border-width": 3, "border-color": "#000", label: "data(downLabel)" } },
        { selector: "edge", style: { width: 2, "line-color": "data(color)" } },
        { selector: "edge.route", style: { width: 5, "line-color": "#1565c0" } },
      ],
      elements: [],
    });
    cy.on("tap", "node", (e) => { $("node").value = e.target.id(); });
  }
  const have = new Set(cy.nodes().map((n) => n.id()));
  let added = false;
  for (const [id, n] of Object.entries(topo.nodes)) {
    if (!have.has(id)) {
      const p = pos[id];
      cy.add({ group: "nodes", data: { id, kind: n.kind }, position: p ? { x: p[0] * 3, y: -p[1] * 3 } : undefined });
      $("node").add(new Option(id, id)); added = true;
    }
    const node = cy.getElementById(id);
    const b = n.battery === null || n.battery === undefined ? 100 : n.battery;
    node.data({ color: b > 66 ? "#2e7d32" : b > 33 ? "#f9a825" : "#c62828", downLabel: `${id} (down)`,
                battery: b });
    node.toggleClass("down", !n.up);
  }
  const edges = new Set();
  for (const l of topo.links) {
    const id = [l.a, l.b].sort().join("|"); edges.add(id);
    if (cy.getElementById(id).empty()) {
      cy.add({ group: "edges", data: { id, source: l.a, target: l.b } });
      $("link").add(new Option(`${l.a}–${l.b}`, id)); added = true;
    }
    const e = cy.getElementById(id);
    e.data({ color: l.prr >= 0.95 ? "#2e7d32" : l.prr >= 0.8 ? "#f9a825" : "#c62828", prr: l.prr });
    e.toggleClass("route", onRoute.has(id));
  }
  cy.edges().forEach((e) => { if (!edges.has(e.id())) e.remove(); });
  if (added) {
    const preset = Object.values(pos).every((p) => p);
    cy.layout(preset ? { name: "preset" } : { name: "breadthfirst", roots: cy.nodes("[kind = 'gateway']"), directed: false, padding: 10 }).run();
  }
}

function drawPaths() {
  const routes = cyNet ? (lastAt(`routes/${cyNet}`, cursor) || { routes: {} }).routes : {};
  const rows = streams("pathstats/").map((name) => {
    const s = lastAt(name, cursor); const path = name.slice(10);
    if (!s) return "";
    const reasons = Object.entries(s.reasons).map(([k, v]) => `${k}: ${v}`).join(", ");
    return `<tr><td>${path}</td><td class="route">${(routes[path] || []).join("→")}</td><td class="num">${fmt(s.last)}</td>
      <td class="num">${fmt(s.mean)}</td><td class="num">${fmt(s.p95)}</td><td class="num">${s.n}</td>
      <td class="num" title="${reasons}">${s.lost}${reasons ? " (" + reasons + ")" : ""}</td></tr>`;
  });
  $("paths").tBodies[0].innerHTML = rows.join("");
}

function describe(r) {
  const t = `<span class="t">${fmt(r.t, 5)}</span>`;
  if (r.kind === "decision") {
    const what = r.subject === "proposal" ? `proposal ${r.proposal}` : r.subject;
    return [`decision ${r.verdict}`, `${t}<b>${r.verdict}</b> ${what}<div class="reasons">${r.reasons.join("<br>")}</div>`];
  }
  if (r.kind === "proposal") {
    const routes = Object.entries(r.routes).map(([p, rt]) => `${p}: ${rt.join("→")}`).join("<br>");
    return ["proposal", `${t}proposal ${r.id} (${r.source}: ${r.event})<div class="reasons">${routes}</div>`];
  }
  if (r.kind === "applied") {
    const routes = Object.entries(r.routes).map(([p, rt]) => `${p}: ${rt.join("→") || "down"}`).join("<br>");
    return ["applied", `${t}applied: ${r.event} (${r.source})${r.reason ? " — " + r.reason : ""}<div class="reasons">${routes}</div>`];
  }
  if (r.kind === "rates") {
    const p = Object.entries(r.periods).map(([l, v]) => `${l} ${fmt(v, 3)}${r.closed[l] ? "" : " (open)"}`).join(", ");
    return ["rates", `${t}rates (${r.mode}${r.method ? ", " + r.method : ""}): ${p}`];
  }
  return ["request", `${t}request ${r.key}: <code>${JSON.stringify(r.body.event || r.body)}</code>`];
}

function drawTimeline() {
  const recs = upto("timeline", cursor);
  if (recs.length === timelineShown) return;
  timelineShown = recs.length;
  const ol = $("timeline");
  ol.innerHTML = recs.map((r) => { const [cls, html] = describe(r); return `<li class="${cls}">${html}</li>`; }).join("");
  ol.scrollTop = ol.scrollHeight;
}

function drawInvalid() {
  const counts = {};
  for (const r of upto("invalid", cursor)) counts[r.key] = [((counts[r.key] || [0])[0]) + 1, r.reason];
  $("invalid").tBodies[0].innerHTML = Object.entries(counts).sort()
    .map(([k, [n, why]]) => `<tr><td>${k}</td><td class="num">${n}</td><td>${why}</td></tr>`).join("");
  const dropped = finished ? finished.dropped_invalid || {} : {};
  const total = Object.values(dropped).reduce((a, b) => a + b, 0);
  $("dropped").textContent = finished ? `refused by the nodes during the run: ${total}` +
    (total ? ` (${Object.entries(dropped).map(([k, v]) => `${k}: ${v}`).join(", ")})` : "") : "";
}

function drawSchedule() {
  if (!cyNet) return;
  const s = lastAt(`schedule/${cyNet}`, cursor);
  if (!s || s === scheduleShown) return;
  scheduleShown = s;
  $("schedule-card").hidden = false;
  const grid = Array.from({ length: s.channel_offsets }, () => Array(s.length).fill(""));
  for (const c of s.cells) if (c.channel < s.channel_offsets && c.slot < s.length) grid[c.channel][c.slot] = `${c.tx}→${c.rx}`;
  const hue = (txt) => { let h = 0; for (const ch of txt) h = (h * 31 + ch.charCodeAt(0)) % 360; return h; };
  $("schedule").innerHTML = `<p>${s.length} slots × ${s.channel_offsets} channel offsets, ${s.cells.length} cells</p><table>` +
    grid.map((row, ch) => `<tr><th>${ch}</th>` + row.map((c) => c ? `<td title="${c}" style="background:hsl(${hue(c)},60%,60%)"></td>` : "<td></td>").join("") + "</tr>").join("") + "</table>";
}

function draw() {
  if (!info) return;
  if (follow) cursor = latest;
  const slider = $("slider");
  slider.max = Math.max(info.end, latest);
  if (follow || playing) slider.value = cursor;
  const state = finished ? (finished.ok ? "finished" : "ended: " + finished.reason) : live ? "live" : "replay";
  setStatus(state, finished ? "finished" : live ? "live" : "");
  $("simtime").textContent = `t = ${fmt(latest, 5)} / ${info.end} ${info.time_unit}`;
  $("cursor").textContent = `showing t ≤ ${fmt(cursor, 5)}`;
  $("follow").disabled = !live;
  drawLoops(); drawDelays(); drawClock(); drawTopology(); drawPaths(); drawTimeline(); drawInvalid(); drawSchedule();
}
function setStatus(text, cls) { const s = $("status"); s.textContent = text; s.className = `badge ${cls}`; }

function frame() { if (dirty) { dirty = false; try { draw(); } catch (e) { console.error(e); } } setTimeout(() => requestAnimationFrame(frame), 200); }
requestAnimationFrame(frame);

// -- the player ----------------------------------------------------------------------------------
$("slider").addEventListener("input", (e) => { follow = false; $("follow").checked = false; cursor = Number(e.target.value); dirty = true; });
$("follow").addEventListener("change", (e) => { follow = e.target.checked && live; dirty = true; });
$("btn-play").addEventListener("click", () => {
  if (playing) { clearInterval(playing); playing = null; $("btn-play").innerHTML = "&#9654; play"; return; }
  follow = false; $("follow").checked = false;
  if (cursor >= latest) cursor = 0;
  let last = performance.now();
  playing = setInterval(() => {
    const now = performance.now();
    cursor = Math.min(latest, cursor + Number($("speed").value) * (now - last) / 1000); last = now;
    dirty = true;
    if (cursor >= latest && !live) { clearInterval(playing); playing = null; $("btn-play").innerHTML = "&#9654; play"; }
  }, 100);
  $("btn-play").innerHTML = "&#10074;&#10074; pause";
});

// -- acting on the run: the requests wncs inject sends -------------------------------------------
const fields = (id) => $(id).value;
$("btn-node-down").addEventListener("click", () => send({ type: "event", event: "node_down", fields: { node: fields("node") } }, `node_down ${fields("node")}`));
$("btn-node-up").addEventListener("click", () => send({ type: "event", event: "node_up", fields: { node: fields("node") } }, `node_up ${fields("node")}`));
$("btn-link").addEventListener("click", () => {
  const [a, b] = fields("link").split("|");
  send({ type: "event", event: "link_degraded", fields: { a, b, prr: Number(fields("prr")) } }, `link_degraded ${a}–${b} prr=${fields("prr")}`);
});
$("btn-interference").addEventListener("click", () => {
  const channels = fields("channels").split(",").map((c) => Number(c.trim()));
  const f = { channels, prr: Number(fields("iprr")) };
  if (Number(fields("iduration")) > 0) f.duration = Number(fields("iduration"));
  send({ type: "event", event: "interference", fields: f }, `interference ${channels}`);
});
$("btn-mode").addEventListener("click", () => send({ type: "mode", mode: fields("mode") }, `mode ${fields("mode")}`));
$("btn-setpoint").addEventListener("click", () => send({ type: "setpoint", loop: fields("sp-loop"), value: Number(fields("sp-value")) }, `setpoint ${fields("sp-loop")}=${fields("sp-value")}`));

// for tests and the console: what the page holds and shows
window.wncs = {
  store,
  get cursor() { return cursor; },
  get latest() { return latest; },
  get live() { return live; },
  get finished() { return finished; },
  points: (loop) => Number(charts[loop].card.dataset.points),
  timeline: () => upto("timeline", cursor),
  send: (raw) => ws.send(raw),
};
