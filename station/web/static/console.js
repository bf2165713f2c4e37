// The station's console page: one live view (server-sent events), the selected job drawn
// as SVG over its photographed fabric, and the console commands behind the token.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const TOKEN_KEY = "station-console-token";
const state = { view: null, selected: null, followNewest: true, detail: null, detailKey: "",
  questionsKey: "" };

function $(sel) { return document.querySelector(sel); }

function el(tag, attrs = {}, text = "") {
  const node = tag.startsWith("svg:") ? document.createElementNS(SVG, tag.slice(4))
    : document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
  if (text) node.textContent = text;
  return node;
}

function token() { return sessionStorage.getItem(TOKEN_KEY) || ""; }

function say(text, bad = false) {
  const msg = $("#message");
  msg.textContent = text;
  msg.className = bad ? "bad" : "good";
}

// ---------------------------------------------------------------- commands
async function post(url, body, contentType = "application/json") {
  const headers = { "Content-Type": contentType };
  if (token()) headers["X-Station-Token"] = token();
  const response = await fetch(url, { method: "POST", headers, body });
  let answer;
  try { answer = await response.json(); } catch { answer = { ok: false, error: response.statusText }; }
  if (!response.ok || !answer.ok) throw new Error(answer.error || `HTTP ${response.status}`);
  return answer;
}

async function act(action, job, extra = {}) {
  try {
    const answer = await post(`/api/jobs/${job}/${action}`, JSON.stringify(extra));
    say(`job ${answer.job}: ${answer.message}`);
  } catch (err) {
    say(`${action} job ${job}: ${err.message}`, true);
  }
}

async function upload(file) {
  const answer = await post(`/api/uploads?name=${encodeURIComponent(file.name)}`, file,
    "application/octet-stream");
  return answer.upload;
}

async function submit(event) {
  event.preventDefault();
  const pattern = $("#pattern").files[0];
  const fabric = $("#fabric").files[0];
  if (!pattern) return;
  $("#submit-button").disabled = true;
  say(`sending ${pattern.name} ...`);
  try {
    const body = { garment: await upload(pattern), fabric: fabric ? await upload(fabric) : null,
      options: $("#units").value ? { units: $("#units").value } : {} };
    const answer = await post("/api/submit", JSON.stringify(body));
    say(`job ${answer.job.id} queued: ${pattern.name}`);
    state.followNewest = true;
  } catch (err) {
    say(`submit: ${err.message}`, true);
  } finally {
    $("#submit-button").disabled = false;
  }
}

// ---------------------------------------------------------------- the live view
function connect() {
  const source = new EventSource("/api/events");
  source.onopen = () => $("#live").classList.add("on");
  source.onerror = () => $("#live").classList.remove("on");
  source.onmessage = (event) => show(JSON.parse(event.data));
}

function show(view) {
  state.view = view;
  $("#station-name").textContent = view.station.name;
  $("#station-state").textContent = view.station.state
    + (view.station.job ? ` job ${view.station.job}` : "");
  showStations(view.stations);
  if (state.followNewest && view.jobs.length) state.selected = view.jobs[view.jobs.length - 1].id;
  showJobs(view.jobs);
  showJob();
  showQuestions(view.questions);
  showEvents(view.events);
}

function showStations(stations) {
  $("#stations").replaceChildren(...stations.map((s) => el("li", { "data-state": s.state },
    `${s.name}: ${s.state}` + (s.job ? `, job ${s.job}` : "") + (s.step ? ` (${s.step})` : ""))));
}

function showJobs(jobs) {
  const rows = jobs.slice().reverse().map((j) => {
    const row = el("tr", { "data-job": j.id, "data-state": j.state });
    if (j.id === state.selected) row.classList.add("selected");
    const p = j.pieces || {};
    row.append(el("td", {}, String(j.id)), el("td", {}, (j.garment || "").split("/").pop()),
      el("td", { class: "state" }, j.state),
      el("td", {}, `${p.pending || 0} / ${p.cutting || 0} / ${p.cut || 0}`));
    row.addEventListener("click", () => {
      state.selected = j.id;
      state.followNewest = j.id === jobs[jobs.length - 1].id;
      show(state.view);
    });
    return row;
  });
  $("#jobs tbody").replaceChildren(...rows);
}

function showQuestions(questions) {
  // drawn again only when the questions change, so a box the operator is filling in stays
  const key = JSON.stringify(questions.map((q) => [q.job, q.reason]));
  if (key === state.questionsKey) return;
  state.questionsKey = key;
  const boxes = questions.map((q) => {
    const box = el("div", { class: "question", "data-job": q.job, "data-question": q.question });
    box.append(el("p", {}, `Job ${q.job} asks: ${q.reason}`));
    if (q.question === "confirm seams") {
      const picture = el("img", { class: "seams", alt: "the seams found, numbered",
        src: `/api/jobs/${q.job}/files/seams.png?v=${encodeURIComponent(q.reason)}` });
      const list = el("ul", { class: "seams" });
      const yes = el("button", { "data-answer": q.answer }, "Confirm seams");
      yes.addEventListener("click", () => act(q.answer, q.job, seamsAnswer(list)));
      box.append(picture, list, yes);
      // unsure as the question counts them (seams.confirm_below), as seams.png marks them
      const below = Number((q.reason.match(/under confidence ([0-9.]+)/) || [])[1] || 0.5);
      listSeams(q.job, list, below);
      return box;
    }
    const group = el("input", { placeholder: "group (empty: as detected)", size: "22" });
    const yes = el("button", { "data-answer": q.answer }, "Confirm fabric");
    yes.addEventListener("click", () => act(q.answer, q.job, group.value ? { group: group.value } : {}));
    box.append(group, yes);
    return box;
  });
  $("#questions").replaceChildren(...boxes);
}

// The seams found, one tick box each (the unsure ones marked): a seam struck out is
// answered as the operator's whole list of seams, the others kept as found, none inferred
// again (`"infer": false`); all ticked, the seams are confirmed as found.
async function listSeams(jobId, list, below) {
  const response = await fetch(`/api/jobs/${jobId}`);
  if (!response.ok) return;
  const found = (await response.json()).seams;
  if (!found) return;
  list.found = found;
  list.replaceChildren(...found.seams.map((s) => {
    const tick = el("input", { type: "checkbox", "data-seam": s.number });
    tick.checked = true;
    const unsure = s.confidence < below ? " ?" : "";
    const item = el("li", { "data-unsure": unsure ? "yes" : "no" });
    item.append(tick, ` ${s.number}${unsure}: ${s.a} to ${s.b}, ${s.length_mm} mm`
      + ` (confidence ${s.confidence})`);
    return item;
  }));
}

function seamsAnswer(list) {
  const found = list.found;
  if (!found) return {};
  const kept = [...list.querySelectorAll("input[data-seam]")].filter((t) => t.checked)
    .map((t) => Number(t.dataset.seam));
  if (kept.length === found.seams.length) return {};
  const seams = found.seams.filter((s) => kept.includes(s.number)).map((s) =>
    ({ a: s.a, a_ends: s.a_ends, b: s.b, b_ends: s.b_ends }));
  return { seams: { pieces: found.pieces, seams, not_seams: [], infer: false } };
}

function showEvents(events) {
  const mine = events.filter((e) => state.selected === null || e.job_id === state.selected
    || e.job_id === null).slice(-80).reverse();
  $("#events").replaceChildren(...mine.map((e) => el("li", {},
    `${new Date(e.at * 1000).toLocaleTimeString()}  ${e.job_id ? "job " + e.job_id + ": " : ""}${e.message}`)));
}

// ---------------------------------------------------------------- the selected job
function showJob() {
  const job = state.view.jobs.find((j) => j.id === state.selected);
  if (!job) return;
  const now = state.view.progress && state.view.progress.job === job.id ? state.view.progress : null;
  const progress = now && now.step ? ` (${now.step}`
    + (now.fraction !== undefined ? ` ${Math.round(100 * now.fraction)} %)` : ")") : "";
  $("#job-title").textContent = `Job ${job.id}: ${job.state}${progress}`;
  $("#job").dataset.state = job.state;
  $("#job-reason").textContent = job.reason || "";
  const total = Object.values(job.pieces || {}).reduce((a, b) => a + b, 0);
  const key = `${job.id}:${job.state}:${total}`;
  if (key !== state.detailKey) {
    state.detailKey = key;
    loadDetail(job.id);
  }
  paintPieces();
}

async function loadDetail(jobId) {
  const response = await fetch(`/api/jobs/${jobId}`);
  if (!response.ok) return;
  const detail = await response.json();
  if (jobId !== state.selected) return;
  state.detail = { id: jobId, ...detail };
  drawMarker(jobId, detail.marker);
  drawPhoto(jobId, detail);
  const fit = ["fit-reshaped.png", "fit-aligned.png"].find((n) => detail.pictures.includes(n));
  const img = $("#fit");
  if (fit) img.src = `/api/jobs/${jobId}/files/${fit}?v=${state.detailKey}`;
  else img.removeAttribute("src");
  $("#file-links").replaceChildren(...detail.pictures.map((name) => el("a",
    { href: `/api/jobs/${jobId}/files/${name}`, target: "_blank", rel: "noopener" }, name)));
  // a picture the job has not made yet is not shown as an empty frame
  img.closest("figure").hidden = !fit;
  $("#marker").closest("figure").hidden = !detail.marker;
  $("#photo").closest("figure").hidden = !detail.fabric;
  paintPieces();
}

function drawMarker(jobId, marker) {
  const svg = $("#marker");
  svg.replaceChildren();
  if (!marker) { svg.setAttribute("viewBox", "0 0 100 10"); return; }
  svg.setAttribute("viewBox", `0 0 ${marker.length} ${marker.width}`);
  svg.dataset.job = jobId;
  const defs = el("svg:defs");
  const size = Math.max(marker.length, marker.width);
  const tip = size / 90;  // arrow heads and names in fabric mm, readable at any zoom
  const head = el("svg:marker", { id: "arrow", viewBox: "0 0 10 10", refX: "9", refY: "5",
    markerUnits: "userSpaceOnUse", markerWidth: tip, markerHeight: tip,
    orient: "auto-start-reverse" });
  head.append(el("svg:path", { d: "M0,0 L10,5 L0,10 z", class: "grain" }));
  defs.append(head);
  svg.append(defs, el("svg:image", { href: `/api/jobs/${jobId}/cloth.png`, x: 0, y: 0,
    width: marker.length, height: marker.width, preserveAspectRatio: "none" }));
  for (const piece of marker.pieces) {
    const g = el("svg:g", { class: "piece", "data-name": piece.id });
    g.append(el("svg:polygon", { points: piece.outline.map((p) => p.join(",")).join(" "),
      "data-name": piece.id, "data-state": "pending" }));
    if (piece.grainline) {
      const [a, b] = piece.grainline;
      g.append(el("svg:line", { x1: a[0], y1: a[1], x2: b[0], y2: b[1], class: "grain",
        "marker-end": "url(#arrow)" }));
    }
    const xs = piece.outline.map((p) => p[0]), ys = piece.outline.map((p) => p[1]);
    const label = el("svg:text", { x: (Math.min(...xs) + Math.max(...xs)) / 2,
      y: (Math.min(...ys) + Math.max(...ys)) / 2, "font-size": size / 40 }, piece.name);
    g.append(label);
    svg.append(g);
  }
}

function paintPieces() {
  const pieces = state.view && state.view.pieces[String(state.selected)];
  if (!pieces || $("#marker").dataset.job !== String(state.selected)) return;
  const byName = new Map(pieces.map((p) => [p.name, p.state]));
  for (const poly of document.querySelectorAll("#marker polygon")) {
    poly.dataset.state = byName.get(poly.dataset.name) || "pending";
  }
}

function drawPhoto(jobId, detail) {
  const svg = $("#photo");
  svg.replaceChildren();
  const fabric = detail.fabric;
  $("#fabric-group").textContent = !fabric ? "not yet known"
    : `${fabric.group || fabric.kind || "?"}` + (fabric.confidence !== undefined
      ? ` at confidence ${Number(fabric.confidence).toFixed(2)}` : "")
      + (detail.photo_mm_per_px ? "" : " (given as FABRIC.json, no photograph)");
  if (!detail.photo_mm_per_px) return;
  const s = detail.photo_mm_per_px;
  const picture = new Image();
  picture.onload = () => {
    const w = picture.naturalWidth * s, h = picture.naturalHeight * s;
    svg.setAttribute("viewBox", `0 0 ${w} ${h}`);
    svg.append(el("svg:image", { href: picture.src, x: 0, y: 0, width: w, height: h }));
    if (fabric && fabric.w1 && fabric.w2) svg.append(lattice(fabric, w, h));
  };
  picture.src = `/api/jobs/${jobId}/files/rectified.png`;
}

// The detected lattice: lines through the origin along w1 and w2, over the whole photo.
function lattice(fabric, w, h) {
  const g = el("svg:g", { class: "lattice" });
  const [a, b] = [fabric.w1, fabric.w2];
  const o = fabric.origin || [0, 0];
  const det = a[0] * b[1] - a[1] * b[0];
  if (Math.abs(det) < 1e-9) return g;
  const frac = (x, y) => [((x - o[0]) * b[1] - (y - o[1]) * b[0]) / det,
    (-(x - o[0]) * a[1] + (y - o[1]) * a[0]) / det];
  const corners = [[0, 0], [w, 0], [0, h], [w, h]].map(([x, y]) => frac(x, y));
  for (const [along, across, k] of [[a, b, 0], [b, a, 1]]) {
    const lo = Math.floor(Math.min(...corners.map((c) => c[k])));
    const hi = Math.ceil(Math.max(...corners.map((c) => c[k])));
    const reach = Math.max(...corners.map((c) => Math.abs(c[1 - k]))) + 1;
    for (let i = lo; i <= hi && i - lo < 400; i++) {
      const p = [o[0] + i * along[0], o[1] + i * along[1]];
      g.append(el("svg:line", { x1: p[0] - reach * across[0], y1: p[1] - reach * across[1],
        x2: p[0] + reach * across[0], y2: p[1] + reach * across[1] }));
    }
  }
  return g;
}

// ---------------------------------------------------------------- start
document.addEventListener("DOMContentLoaded", () => {
  $("#token").value = token();
  $("#token-form").addEventListener("submit", (event) => {
    event.preventDefault();
    sessionStorage.setItem(TOKEN_KEY, $("#token").value.trim());
    say("token set for this tab");
  });
  $("#submit-form").addEventListener("submit", submit);
  for (const button of document.querySelectorAll("#actions button")) {
    button.addEventListener("click", () => {
      if (state.selected !== null) act(button.dataset.action, state.selected);
    });
  }
  connect();
});
