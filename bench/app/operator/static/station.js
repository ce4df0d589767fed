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
  const {ok, doc} = await post("/api/start", {operator: $("operator").value, sockets});
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

const lastPlotted = {};
function plot(canvas, t, y, key) {
  if (lastPlotted[canvas.id] === key) return;
  lastPlotted[canvas.id] = key;
  const w = canvas.width = canvas.clientWidth * devicePixelRatio;
  const h = canvas.height = canvas.clientHeight * devicePixelRatio;
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, w, h);
  if (t.length < 2) return;
  let t0 = Math.min(...t), t1 = Math.max(...t), y0 = Math.min(...y), y1 = Math.max(...y);
  if (t1 === t0) t1 = t0 + 1;
  if (y1 === y0) { y0 -= 1e-9; y1 += 1e-9; }
  const pad = 4 * devicePixelRatio;
  g.strokeStyle = "#3b6fd8"; g.lineWidth = devicePixelRatio; g.beginPath();
  for (let i = 0; i < t.length; i++) {
    const x = pad + (t[i] - t0) / (t1 - t0) * (w - 2 * pad);
    const yy = h - pad - (y[i] - y0) / (y1 - y0) * (h - 2 * pad);
    if (i === 0) g.moveTo(x, yy); else g.lineTo(x, yy);
  }
  g.stroke();
  g.fillStyle = "#555"; g.font = `${10 * devicePixelRatio}px sans-serif`;
  g.fillText(`${y1.toPrecision(7)}`, pad, 11 * devicePixelRatio);
  g.fillText(`${y0.toPrecision(7)}`, pad, h - pad);
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
      <div class="label" style="font-size:12px;color:#555"></div><canvas id="plot-${s.socket}"></canvas>
      <table class="measurements"><thead><tr><th>measurement</th><th>value</th><th>unit</th><th>limits</th><th></th></tr></thead><tbody></tbody></table>
      <a class="report"></a>`;
    $("sockets").appendChild(card);
  }
  card.querySelector(".serial").textContent = s.serial;
  card.querySelector(".status").textContent = s.status;
  const v = card.querySelector(".verdict");
  v.textContent = s.verdict || ""; v.className = "verdict " + verdictClass(s.verdict);
  card.querySelector(".reason").textContent = s.reason || "";
  card.querySelector(".label").textContent = s.label || "";
  plot(card.querySelector("canvas"), s.t, s.y, `${s.stream}:${s.t.length}:${s.t[s.t.length - 1]}`);
  const rows = s.measurements.map((m) => {
    const lim = `${m.low ?? ""} … ${m.high ?? ""}`;
    const value = m.value === null ? "—" : Number(m.value).toPrecision(6);
    return `<tr><td>${esc(m.name)}</td><td>${value}</td><td>${esc(m.unit)}</td><td>${lim}</td><td class="${m.outcome}">${m.outcome.toUpperCase()}</td></tr>`;
  }).join("");
  const body = card.querySelector("tbody");
  if (body.dataset.rows !== String(s.measurements.length)) { body.innerHTML = rows; body.dataset.rows = s.measurements.length; }
  const a = card.querySelector(".report");
  if (s.report) { a.href = s.report; a.textContent = "report"; a.target = "_blank"; } else { a.removeAttribute("href"); a.textContent = ""; }
}

function render(st) {
  window.stateMessages++;
  $("station-state").textContent = st.state + (st.operator ? ` — operator ${st.operator}` : "");
  $("spec").textContent = st.spec ? `spec ${st.spec}` : "";
  $("prompt").classList.toggle("hidden", !st.prompt);
  $("prompt-text").textContent = st.prompt ? st.prompt.text : "";
  const busy = st.state === "prompt" || st.state === "running";
  $("start").disabled = busy;
  $("abort").classList.toggle("hidden", !busy);
  lastSnapshot = st;
  $("retest").classList.toggle("hidden", retestable(st).length === 0);
  $("progress").style.width = `${(100 * st.fraction).toFixed(1)}%`;
  const left = st.wall_left_s == null ? "" : ` — about ${Math.ceil(st.wall_left_s)} s left`;
  $("progress-text").textContent = `${(100 * st.fraction).toFixed(0)}% ${st.message || ""}${left}` + (st.error ? ` — ${st.error}` : "");
  $("steps").innerHTML = st.steps.map((s) => `<li class="${s.state}">${esc(s.name)} (${(s.duration_s / 60).toFixed(0)} min)</li>`).join("");
  const shown = new Set(st.sockets.map((s) => `socket-${s.socket}`));
  for (const card of [...$("sockets").children]) if (!shown.has(card.id)) card.remove();
  st.sockets.forEach(socketCard);
  document.body.dataset.state = st.state;
}

function listen() {
  const source = new EventSource("/api/events");
  source.onmessage = (e) => render(JSON.parse(e.data));
  source.onerror = () => { source.close(); setTimeout(listen, 1000); };
}

async function searchHistory() {
  const q = new URLSearchParams({serial: $("history-serial").value, verdict: $("history-verdict").value, date: $("history-date").value});
  const doc = await (await fetch(`/api/history?${q}`)).json();
  $("history-table").querySelector("tbody").innerHTML = doc.runs.map((r) =>
    `<tr><td>${esc(r.run_id)}</td><td>${esc(r.serial)}</td><td>${esc(r.socket)}</td><td>${esc(r.started_utc)}</td><td class="${r.verdict === "FAIL" ? "fail" : ""}">${esc(r.verdict)}</td><td>${r.report ? `<a href="${r.report}" target="_blank">report</a>` : ""}</td></tr>`).join("");
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
$("history-search").addEventListener("click", searchHistory);
$("doctor-run").addEventListener("click", doctor);
listen();
