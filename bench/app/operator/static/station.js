// The operator page: one live snapshot from the server (Server-Sent Events), drawn whole.
"use strict";
const SOCKETS = 8;
window.plotUpdates = 0;        // how many times a live plot was redrawn with new data (measured)
window.stateMessages = 0;      // snapshots received
const $ = (id) => document.getElementById(id);
const esc = (s) => String(s ?? "").replace(/[&<>"]/g, (c) => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;"}[c]));

function buildSerials() {
  const box = $("serials");
  for (let n = 1; n <= SOCKETS; n++) {
    const label = document.createElement("label");
    label.innerHTML = `Socket ${n} <input id="serial-${n}" data-socket="${n}" autocomplete="off">`;
    box.appendChild(label);
  }
  // a barcode scanner types the serial and Enter: go to the next socket (or start after the last)
  box.addEventListener("keydown", (e) => {
    if (e.key !== "Enter") return;
    e.preventDefault();
    const n = Number(e.target.dataset.socket);
    if (n < SOCKETS) $(`serial-${n + 1}`).focus(); else $("start").focus();
  });
}

async function post(url, body) {
  const r = await fetch(url, {method: "POST", headers: {"Content-Type": "application/json"},
                              body: JSON.stringify(body || {})});
  let doc = {};
  try { doc = await r.json(); } catch (e) { doc = {error: `server answered ${r.status}`}; }
  return {ok: r.ok, doc};
}

async function start() {
  const sockets = {};
  for (let n = 1; n <= SOCKETS; n++) sockets[n] = $(`serial-${n}`).value.trim();
  $("error").textContent = "";
  const {ok, doc} = await post("/api/start", {operator: $("operator").value, sockets, seed: $("seed").value});
  if (!ok) $("error").textContent = doc.error;
}

// Retest: the sockets whose unit failed or aborted, with the same serials, as a new batch
let lastSnapshot = null;
function retestable(st) {
  return (st && (st.state === "done" || st.state === "aborted"))
    ? st.sockets.filter((s) => s.verdict === "FAIL" || s.verdict === "ABORTED") : [];
}
async function retest() {
  const again = new Map(retestable(lastSnapshot).map((s) => [s.socket, s.serial]));
  if (!again.size) return;
  for (let n = 1; n <= SOCKETS; n++) $(`serial-${n}`).value = again.get(n) || "";
  if (!$("operator").value.trim()) $("operator").value = lastSnapshot.operator;  // after a reload
  await start();
}

// ticks at 1, 2 or 5 × 10^n: about `count` of them over [lo, hi]
function ticks(lo, hi, count) {
  const raw = (hi - lo) / count, mag = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
  return {values: out, step};
}
function tickText(v, step) {  // as many decimals as the step needs, a true minus sign
  const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  const text = Math.abs(v) >= 1e5 || (v !== 0 && Math.abs(v) < 1e-4) ? v.toExponential(2) : v.toFixed(decimals);
  return text.replace("-", "\u2212");
}

const lastPlotted = {};
function plot(canvas, t, y, key, xLabel) {
  if (lastPlotted[canvas.id] === key) return;
  lastPlotted[canvas.id] = key;
  const px = devicePixelRatio;
  const w = canvas.width = canvas.clientWidth * px;
  const h = canvas.height = canvas.clientHeight * px;
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, w, h);
  if (t.length < 2) return;
  let t0 = Math.min(0, ...t), t1 = Math.max(...t), y0 = Math.min(...y), y1 = Math.max(...y);
  if (t1 === t0) t1 = t0 + 1;
  if (y1 === y0) { const d = Math.abs(y0) * 1e-6 || 1e-9; y0 -= d; y1 += d; }
  g.font = `${10 * px}px sans-serif`;
  const ystep = ticks(y0, y1, 3).step;  // the y range widened to whole ticks: both ends labelled
  y0 = Math.floor(y0 / ystep) * ystep; y1 = Math.ceil(y1 / ystep) * ystep;
  const yt = ticks(y0, y1, 3), xt = ticks(t0, t1, 5);
  const left = 6 * px + Math.max(...yt.values.map((v) => g.measureText(tickText(v, yt.step)).width));
  const top = 8 * px, bottom = 28 * px, right = 8 * px;
  const X = (v) => left + (v - t0) / (t1 - t0) * (w - left - right);
  const Y = (v) => h - bottom - (v - y0) / (y1 - y0) * (h - top - bottom);
  g.strokeStyle = "#ccd"; g.fillStyle = "#555"; g.lineWidth = px;
  g.textAlign = "right"; g.textBaseline = "middle";
  for (const v of yt.values) {  // y grid and its values
    g.beginPath(); g.moveTo(left, Y(v)); g.lineTo(w - right, Y(v)); g.stroke();
    g.fillText(tickText(v, yt.step), left - 3 * px, Y(v));
  }
  g.textAlign = "center"; g.textBaseline = "top";
  for (const v of xt.values) {  // the time axis: seconds since the step's record began
    g.beginPath(); g.moveTo(X(v), h - bottom); g.lineTo(X(v), h - bottom + 3 * px); g.stroke();
    g.fillText(tickText(v, xt.step), X(v), h - bottom + 4 * px);
  }
  g.beginPath(); g.moveTo(left, h - bottom); g.lineTo(w - right, h - bottom); g.stroke();
  g.textAlign = "right"; g.fillText(xLabel, w - right, h - 12 * px);
  g.strokeStyle = "#3b6fd8"; g.beginPath();
  for (let i = 0; i < t.length; i++) {
    if (i === 0) g.moveTo(X(t[i]), Y(y[i])); else g.lineTo(X(t[i]), Y(y[i]));
  }
  g.stroke();
  canvas.dataset.xLabel = xLabel;
  canvas.dataset.xRange = `${tickText(t0, xt.step)} ${tickText(t1, xt.step)}`;
  canvas.setAttribute("aria-label", `plot against ${xLabel}, ${canvas.dataset.xRange.replace(" ", " to ")}`);
  window.plotUpdates++;
}

function verdictClass(v) {
  if (!v) return "";
  if (v.startsWith("PASS (marginal)")) return "PASS MARGINAL";
  return v.split(" ")[0];
}

function socketCard(s) {
  let card = $(`socket-${s.socket}`);
  if (!card) {
    card = document.createElement("div");
    card.className = "card"; card.id = `socket-${s.socket}`;
    card.innerHTML = `<b>Socket ${s.socket}</b> <span class="serial"></span> — <span class="status"></span>
      <div class="verdict"></div><div class="reason" style="font-size:12px"></div>
      <div class="label" style="font-size:12px;color:#555"></div><canvas id="plot-${s.socket}" role="img"></canvas>
      <table class="measurements"><thead><tr><th>measurement</th><th class="num">value</th><th>limits</th><th></th></tr></thead><tbody></tbody></table>
      <a class="report"></a> <span class="seed"></span>`;
    $("sockets").appendChild(card);
  }
  card.querySelector(".serial").textContent = s.serial;
  card.querySelector(".status").textContent = s.status;
  const v = card.querySelector(".verdict");
  v.textContent = s.verdict || ""; v.className = "verdict " + verdictClass(s.verdict);
  card.querySelector(".reason").textContent = s.reason || "";
  card.querySelector(".label").textContent = s.label || "";
  plot(card.querySelector("canvas"), s.t, s.y, `${s.stream}:${s.t.length}:${s.t[s.t.length - 1]}`, s.x_label);
  const rows = s.measurements.map((m) =>
    `<tr><td title="${esc(m.name)}: ${esc(m.description)}">${esc(m.label)}</td><td class="num" title="${esc(m.uncertainty_text)}">${esc(m.value_text)} <span class="unit">${esc(m.unit_text)}</span></td>` +
    `<td class="limits">${esc(m.limits_text)}</td><td class="outcome ${m.outcome}">${m.outcome.toUpperCase()}</td></tr>`).join("");
  const body = card.querySelector("tbody");
  if (body.dataset.rows !== String(s.measurements.length)) { body.innerHTML = rows; body.dataset.rows = s.measurements.length; }
  const a = card.querySelector(".report");
  if (s.report) { a.href = s.report; a.textContent = "report"; a.target = "_blank"; } else { a.removeAttribute("href"); a.textContent = ""; }
  card.querySelector(".seed").textContent = lastSnapshot && lastSnapshot.seed_text ? `seed ${lastSnapshot.seed_text}` : "";
}

function duration(s) { return s < 90 ? `${Math.round(s)} s` : s < 5400 ? `${Math.round(s / 60)} min` : `${(s / 3600).toFixed(1)} h`; }

function render(st) {
  window.stateMessages++;
  $("station-state").textContent = st.state + (st.operator ? ` — operator ${st.operator}` : "");
  $("spec").textContent = st.spec ? `spec ${st.spec}` : "";
  $("prompt").classList.toggle("hidden", !st.prompt);
  $("prompt-text").textContent = st.prompt ? st.prompt.text : "";
  const busy = st.state === "prompt" || st.state === "running";
  $("start").disabled = busy;
  $("abort").classList.toggle("hidden", !busy);
  const ended = lastSnapshot && (lastSnapshot.state === "prompt" || lastSnapshot.state === "running") && !busy;
  lastSnapshot = st;
  if (st.station) $("seed-field").classList.toggle("hidden", !st.station.seeded);
  $("live-seed").textContent = st.seed_text ? `seed ${st.seed_text}` : "";
  $("retest").classList.toggle("hidden", retestable(st).length === 0);
  $("progress").style.width = `${(100 * st.fraction).toFixed(1)}%`;
  const left = st.time_left ? ` — ${st.time_left}` : "";
  $("progress-text").textContent = `${(100 * st.fraction).toFixed(0)}% ${st.message || ""}${left}` + (st.error ? ` — ${st.error}` : "");
  $("steps").innerHTML = st.steps.map((s) => `<li class="${s.state}" title="${esc(s.name)}">${esc(s.title)} (${duration(s.duration_s)})</li>`).join("");
  const shown = new Set(st.sockets.map((s) => `socket-${s.socket}`));
  for (const card of [...$("sockets").children]) if (!shown.has(card.id)) card.remove();
  st.sockets.forEach(socketCard);
  document.body.dataset.state = st.state;
  if (ended) loadHistory();  // the batch's runs are stored: show them
}

function listen() {
  const source = new EventSource("/api/events");
  source.onmessage = (e) => render(JSON.parse(e.data));
  source.onerror = () => { source.close(); setTimeout(listen, 1000); };
}

// History: the stored runs, newest first, loaded with the page and after every batch; the
// filter keeps the rows where every word is found in the serial, procedure, result or date
let historyRows = [];
async function loadHistory() {
  const r = await fetch("/api/history");
  if (!r.ok) return;
  historyRows = (await r.json()).runs;
  showHistory();
}
function showHistory() {
  const words = $("history-filter").value.toLowerCase().split(/\s+/).filter(Boolean);
  const rows = historyRows.filter((r) => {
    const text = [r.serial, r.procedure_text, r.result, r.started_utc].join(" ").toLowerCase();
    return words.every((w) => text.includes(w));
  });
  $("history-count").textContent = `${rows.length} of ${historyRows.length} stored runs`;
  $("history-table").querySelector("tbody").innerHTML = rows.map((r) => {
    const cls = r.verdict == null ? "status" : r.verdict === "FAIL" ? "fail" : r.verdict.startsWith("PASS (marginal)") ? "marginal" : "";
    const why = r.verdict == null ? "not an acceptance: the run's own status, no spec judged" : (r.reason || "");
    return `<tr data-run="${esc(r.run_id)}"><td>${esc(r.started_utc.slice(0, 19).replace("T", " "))}</td><td>${esc(r.serial)}</td><td class="procedure">${esc(r.procedure_text)}</td>` +
      `<td class="result ${cls}" title="${esc(why)}">${esc(r.result)}</td><td>${esc(r.socket)}</td><td class="seed-cell">${esc(r.seed_text)}</td>` +
      `<td>${r.report ? `<a href="${r.report}" target="_blank">report</a>` : ""}</td><td>${esc(r.run_id)}</td></tr>`;
  }).join("");
}

async function doctor() {
  const r = await fetch("/api/doctor");
  const doc = await r.json();
  const body = $("doctor-table").querySelector("tbody");
  if (!r.ok) { body.innerHTML = `<tr><td colspan="5">${esc(doc.error)}</td></tr>`; return; }
  body.innerHTML = doc.instruments.map((h) =>
    `<tr><td>${esc(h.name)}</td><td>${esc(h.driver)}</td><td class="${h.status === "FAIL" ? "fail" : ""}">${esc(h.status)}</td><td>${esc(h.reason || h.identity)}</td><td>${h.round_trip_ms == null ? "" : h.round_trip_ms.toFixed(1) + " ms"}</td></tr>`).join("");
}

async function whoami() {  // logged in (a station served beyond loopback): the login runs the batch
  const r = await fetch("/api/whoami");
  const doc = r.ok ? await r.json() : {};
  if (doc.user) { $("operator").value = doc.user; $("operator").readOnly = true; $("operator").title = `logged in as ${doc.role}`; }
}

buildSerials();
whoami();
$("start").addEventListener("click", start);
$("abort").addEventListener("click", () => post("/api/abort"));
$("retest").addEventListener("click", retest);
$("prompt-continue").addEventListener("click", () => post("/api/prompt", {answer: "continue"}));
$("prompt-abort").addEventListener("click", () => post("/api/prompt", {answer: "abort"}));
$("history-refresh").addEventListener("click", loadHistory);
$("history-filter").addEventListener("input", showHistory);
$("doctor-run").addEventListener("click", doctor);
loadHistory();
listen();
