// The render service's dashboard: polls the server's JSON API (/api/, the same reads as the
// gRPC API, with the same bearer token), draws the job and worker tables, the selected job's
// live preview beside its per-pixel variance and sample-count maps, and its error-against-time
// plot. Plain JavaScript, no build step, no library.
"use strict";

const REFRESH_MS = 1000;
const tokenInput = document.getElementById("token");
tokenInput.value = localStorage.getItem("render-token") || "";
tokenInput.addEventListener("change", () => {
  localStorage.setItem("render-token", tokenInput.value);
  refresh();
});

let selected = null;          // job id shown in the detail pane
let selectedFrame = 0;
let previewKey = "";          // job/frame/iterations of the preview on screen
let previewUrl = null;

function headers() {
  const t = tokenInput.value.trim();
  return t ? { Authorization: "Bearer " + t } : {};
}

async function api(path, options = {}) {
  const response = await fetch(path, { ...options, headers: headers() });
  if (!response.ok) {
    let message = response.statusText;
    try { message = (await response.json()).error || message; } catch (e) { /* not JSON */ }
    throw new Error(`${path}: ${response.status} ${message}`);
  }
  return response;
}

function stateName(s) { return String(s).replace("JOB_STATE_", ""); }

// Fraction done of a job: iterations over the target, or render time over a pure time budget.
function progress(job) {
  let done = 0, total = 0;
  const budget = Number(job.settings.time_budget_seconds || 0);
  for (const f of job.frames) {
    if (f.done) { done += 1; total += 1; continue; }
    const target = Number(f.iterations_target);
    if (target > 0) {
      let frac = Number(f.iterations_done) / target;
      if (budget > 0) frac = Math.max(frac, Number(f.render_seconds) / budget);
      done += Math.min(frac, 1);
    } else if (budget > 0) {
      done += Math.min(Number(f.render_seconds) / budget, 1);
    }
    total += 1;
  }
  return total ? done / total : 0;
}

function fmt(x, digits = 3) {
  if (!isFinite(x)) return "–";
  if (x === 0) return "0";
  if (Math.abs(x) >= 1e5 || Math.abs(x) < 1e-3) return x.toExponential(2);
  return Number(x.toPrecision(digits)).toString();
}

function fmtSeconds(s) {
  if (!(s > 0)) return "–";
  if (s < 60) return s.toFixed(1) + " s";
  if (s < 3600) return Math.floor(s / 60) + " min " + Math.round(s % 60) + " s";
  return (s / 3600).toFixed(1) + " h";
}

function cell(text, cls) {
  const td = document.createElement("td");
  td.textContent = text;
  if (cls) td.className = cls;
  return td;
}

function button(label, cls, job, onClick) {
  const b = document.createElement("button");
  b.textContent = label;
  b.className = cls;
  b.dataset.job = job;
  b.addEventListener("click", (e) => { e.stopPropagation(); onClick(); });
  return b;
}

async function action(path) {
  try {
    await api(path, { method: "POST" });
    setStatus("");
  } catch (e) {
    setStatus(e.message);
  }
  refresh();
}

function setStatus(text) { document.getElementById("status").textContent = text; }

function drawJobs(jobs) {
  const body = document.querySelector("#jobs tbody");
  body.replaceChildren();
  for (const job of jobs) {
    const state = stateName(job.state);
    const tr = document.createElement("tr");
    tr.className = "job" + (job.id === selected ? " selected" : "");
    tr.dataset.job = job.id;
    tr.dataset.state = state;
    const ended = ["DONE", "CANCELLED", "FAILED"].includes(state);
    const active = ended ? [] : job.frames.filter((f) => !f.done);
    const rate = active.reduce((a, f) => a + Number(f.iterations_per_second), 0);
    const eta = Math.max(0, ...active.map((f) => Number(f.eta_seconds)));
    const error = Math.max(0, ...job.frames.map((f) => Number(f.relative_error)));
    const p = state === "DONE" ? 1 : progress(job);
    const pct = Math.floor(p * 100 + 1e-9);
    tr.append(cell(job.id, "id"), cell(job.name), cell(state, "state state-" + state));
    const prog = document.createElement("td");
    prog.className = "progress";
    const bar = document.createElement("span");
    bar.className = "bar";
    const fill = document.createElement("span");
    fill.style.width = pct + "%";
    bar.append(fill);
    const label = document.createElement("span");
    label.className = "percent";
    label.textContent = pct + " %";
    prog.append(bar, label);
    tr.append(prog, cell(active.length ? fmt(rate) : "–", "num"),
              cell(active.length ? fmtSeconds(eta) : "–", "num"), cell(fmt(error), "num error"));
    const prio = document.createElement("td");
    prio.append(document.createTextNode(job.priority + " "));
    if (!ended) {
      prio.append(button("+", "priority-up", job.id,
                         () => action(`/api/jobs/${job.id}/priority?value=${job.priority + 1}`)),
                  button("−", "priority-down", job.id,
                         () => action(`/api/jobs/${job.id}/priority?value=${job.priority - 1}`)));
    }
    const ops = document.createElement("td");
    if (!ended) ops.append(button("Cancel", "cancel", job.id,
                                  () => action(`/api/jobs/${job.id}/cancel`)));
    if (job.error) ops.append(document.createTextNode(" " + job.error));
    if (job.waiting) ops.append(document.createTextNode(" " + job.waiting));
    tr.append(prio, ops);
    tr.addEventListener("click", () => select(job.id));
    body.append(tr);
  }
}

// This server's workers (/api/cluster, with their leases) and, with several servers on one
// queue, the other servers' (/api/farm, as the store has them from their last sync).
function drawWorkers(cluster, farm) {
  const body = document.querySelector("#workers tbody");
  body.replaceChildren();
  const now = Date.now();
  const others = farm && farm.shared ? (farm.workers || []).filter((w) => !w.self) : [];
  for (const w of cluster.workers || []) {
    const tr = document.createElement("tr");
    tr.dataset.worker = w.worker_id;
    const r = w.rates || {};
    tr.append(cell(w.worker_id), cell(w.host), cell(String(w.threads), "num"),
              cell(fmt(Number(r.iterations_per_second || 0)), "num"),
              cell(fmt(Number(r.samples_per_second || 0)), "num"),
              cell(fmt(Number(r.rays_per_second || 0)), "num"),
              cell(w.lease_id ? `${w.active_leases} (${w.lease_id})` : "idle"),
              cell(fmtSeconds((now - Number(w.last_seen_unix_ms)) / 1000) + " ago"));
    body.append(tr);
  }
  for (const w of others) {
    const tr = document.createElement("tr");
    tr.dataset.worker = w.worker_id;
    tr.dataset.server = w.server;
    tr.append(cell(w.worker_id), cell(w.host), cell(String(w.threads), "num"),
              cell(fmt(Number(w.iterations_per_second || 0)), "num"),
              cell(fmt(Number(w.samples_per_second || 0)), "num"),
              cell(fmt(Number(w.rays_per_second || 0)), "num"),
              cell(`on ${w.server}`),
              cell(fmtSeconds((now - Number(w.last_seen_unix_ms)) / 1000) + " ago"));
    body.append(tr);
  }
  document.getElementById("summary").textContent =
    `${cluster.queued_jobs} queued, ${cluster.running_jobs} running, ` +
    `${cluster.waiting_jobs || 0} waiting for memory, ` +
    `${(cluster.workers || []).length + others.length} workers`;
}

// Several servers on one queue (/api/farm): each server and the jobs it holds.
function drawFarm(farm) {
  document.getElementById("farm").hidden = !farm.shared;
  if (!farm.shared) return;
  const body = document.querySelector("#servers tbody");
  body.replaceChildren();
  for (const s of farm.servers || []) {
    const tr = document.createElement("tr");
    tr.dataset.server = s.address;
    tr.append(cell(s.self ? `${s.address} (this server)` : s.address),
              cell(String(s.jobs_held), "num"));
    body.append(tr);
  }
  document.getElementById("farm-unheld").textContent =
    `${farm.jobs_unheld} unfinished jobs held by no server.`;
}

function select(id) {
  selected = id;
  selectedFrame = 0;
  previewKey = "";
  refresh();
}

async function drawDetail(jobs) {
  const pane = document.getElementById("detail");
  const job = jobs.find((j) => j.id === selected);
  if (!job) { pane.hidden = true; return; }
  pane.hidden = false;
  document.getElementById("detail-id").textContent = job.id;
  const frames = document.getElementById("detail-frame");
  if (frames.options.length !== job.frames.length) {
    frames.replaceChildren(...job.frames.map((f) => new Option("frame " + f.index, f.index)));
    frames.onchange = () => { selectedFrame = Number(frames.value); previewKey = ""; refresh(); };
  }
  frames.value = selectedFrame;
  const frame = job.frames[selectedFrame];
  const key = `${job.id}/${selectedFrame}/${frame.iterations_done}/${frame.done}`;
  if (key !== previewKey && Number(frame.iterations_done) > 0) {
    // A new merge: fetch the preview (with the token, hence fetch and a blob URL).
    const response = await api(`/api/jobs/${job.id}/preview.png?frame=${selectedFrame}`);
    const blob = await response.blob();
    const img = document.getElementById("preview");
    const url = URL.createObjectURL(blob);
    await new Promise((resolve) => { img.onload = resolve; img.onerror = resolve; img.src = url; });
    if (previewUrl) URL.revokeObjectURL(previewUrl);
    previewUrl = url;
    img.width = Math.max(256, img.naturalWidth);
    img.dataset.job = job.id;
    img.dataset.frame = String(selectedFrame);
    img.dataset.iterations = String(frame.iterations_done);
    img.dataset.done = String(frame.done);
    document.getElementById("preview-caption").textContent =
      `${frame.iterations_done} iterations, tone-mapped preview (clamp, sRGB)`;
    await Promise.all([loadMap("variance", job.id, img.width),
                       loadMap("samples", job.id, img.width)]);
    previewKey = key;
  }
  const history = await (await api(`/api/jobs/${job.id}/history?frame=${selectedFrame}`)).json();
  drawPlot(history.points);
}

// One of the maps beside the preview (the server's /variance.png and /samples.png): a false-colour
// PNG whose ramp ends the headers give; a map the server cannot make (a finished frame without a
// variance layer) is hidden and its caption says why.
const mapUrls = {};
async function loadMap(kind, jobId, width) {
  const img = document.getElementById(`${kind}-map`);
  const caption = document.getElementById(`${kind}-caption`);
  const response = await fetch(`/api/jobs/${jobId}/${kind}.png?frame=${selectedFrame}`,
                               { headers: headers() });
  if (!response.ok) {
    let message = response.statusText;
    try { message = (await response.json()).error || message; } catch (e) { /* not JSON */ }
    img.hidden = true;
    img.nextElementSibling.hidden = true;
    img.dataset.job = jobId;
    caption.textContent = `${kind === "variance" ? "variance" : "samples"}: ${message}`;
    return;
  }
  const url = URL.createObjectURL(await response.blob());
  await new Promise((resolve) => { img.onload = resolve; img.onerror = resolve; img.src = url; });
  if (mapUrls[kind]) URL.revokeObjectURL(mapUrls[kind]);
  mapUrls[kind] = url;
  img.hidden = false;
  img.nextElementSibling.hidden = false;
  img.width = width;
  img.nextElementSibling.style.width = `${width}px`;  // the ramp under the map, as wide
  img.dataset.job = jobId;
  const low = Number(response.headers.get("X-Map-Low"));
  const high = Number(response.headers.get("X-Map-High"));
  img.dataset.low = String(low);
  img.dataset.high = String(high);
  if (kind === "variance") {
    const source = response.headers.get("X-Map-Source");
    caption.textContent = `variance of each pixel's estimate (${source}), log scale: ` +
      `${low.toPrecision(3)} to ${high.toPrecision(3)}; grey: unknown`;
  } else {
    caption.textContent = low === high ? `samples per pixel: ${low} everywhere`
                                       : `samples per pixel: ${low} to ${high}`;
  }
}

// Estimated relative error against render time, log-scale y, drawn by hand on a canvas.
function drawPlot(points) {
  const canvas = document.getElementById("plot");
  const g = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 56, R = 12, T = 12, B = 34;
  g.clearRect(0, 0, W, H);
  g.font = "11px system-ui, sans-serif";
  g.strokeStyle = "#889";
  g.strokeRect(L, T, W - L - R, H - T - B);
  // One iteration has no odd/even estimate (the server reports 1): not plotted.
  const pts = points.filter((p) => p.iterations >= 2 && p.relative_error > 0 &&
                                   isFinite(p.relative_error));
  g.fillStyle = "#334";
  g.fillText("seconds", W / 2 - 20, H - 4);
  if (!pts.length) { g.fillText("no merged reports yet", L + 10, T + 20); return; }
  const xMax = Math.max(1e-3, ...pts.map((p) => p.seconds));
  let lo = Math.log10(Math.min(...pts.map((p) => p.relative_error)));
  let hi = Math.log10(Math.max(...pts.map((p) => p.relative_error)));
  lo = Math.floor(lo); hi = Math.ceil(hi); if (hi <= lo) hi = lo + 1;
  const x = (s) => L + (s / xMax) * (W - L - R);
  const y = (e) => T + (hi - Math.log10(e)) / (hi - lo) * (H - T - B);
  g.strokeStyle = "#e2e4ea";
  for (let d = lo; d <= hi; ++d) {
    g.beginPath(); g.moveTo(L, y(10 ** d)); g.lineTo(W - R, y(10 ** d)); g.stroke();
    g.fillText("1e" + d, 8, y(10 ** d) + 4);
  }
  for (let i = 0; i <= 4; ++i) {
    const s = xMax * i / 4;
    g.textAlign = i === 0 ? "left" : i === 4 ? "right" : "center";
    g.fillText(fmt(s, 2), x(s), H - B + 14);
  }
  g.textAlign = "left";
  g.strokeStyle = "#1559c7";
  g.lineWidth = 2;
  g.beginPath();
  pts.forEach((p, i) => (i ? g.lineTo(x(p.seconds), y(p.relative_error))
                           : g.moveTo(x(p.seconds), y(p.relative_error))));
  g.stroke();
  g.lineWidth = 1;
  g.fillStyle = "#1559c7";
  for (const p of pts) g.fillRect(x(p.seconds) - 2, y(p.relative_error) - 2, 4, 4);
}

let busy = false;
async function refresh() {
  if (busy) return;
  busy = true;
  try {
    const [jobs, cluster, farm] = await Promise.all([
      api("/api/jobs").then((r) => r.json()),
      api("/api/cluster").then((r) => r.json()),
      api("/api/farm").then((r) => r.json()),
    ]);
    const list = jobs.jobs || [];
    if (!selected && list.length) selected = list[0].id;
    drawJobs(list);
    drawWorkers(cluster, farm);
    drawFarm(farm);
    await drawDetail(list);
    document.body.dataset.refreshed = String(Date.now());
    setStatus("");
  } catch (e) {
    setStatus(e.message);
  } finally {
    busy = false;
  }
}

refresh();
setInterval(refresh, REFRESH_MS);
