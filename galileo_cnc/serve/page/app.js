// galileo-cnc serve: the page. State comes from the event stream (/api/events); the
// buttons call the JSON API (docs/serve.md). The token sits in a cookie the server set.
"use strict";
const $ = (id) => document.getElementById(id);
let upload = null, plan = null, prompt = null, head = null, activity = null;

async function api(path, body) {
  const options = body === undefined ? {} : {
    method: "POST", headers: {"content-type": "application/json"}, body: JSON.stringify(body)};
  const response = await fetch(path, options);
  const data = await response.json().catch(() => ({}));
  if (!response.ok) { say(data.error || `${path}: HTTP ${response.status}`, true); throw data; }
  return data;
}

function say(text, error) {
  const item = document.createElement("li");
  item.textContent = text;
  if (error) item.className = "error";
  $("messages").append(item);
  item.scrollIntoView({block: "nearest"});
}

function mm(v) { return v === null || v === undefined ? "-" : v.toFixed(3); }

function showStatus(e) {
  const state = $("state");
  state.textContent = e.state;
  state.className = "pill " + (e.state.includes("lost") ? "lost" :
    /alarm/i.test(e.state) ? "alarm" : /run|jog/i.test(e.state) ? "run" : "");
  if (e.position) {
    const [x, y, z] = e.position;
    $("position").textContent = `X ${mm(x)} Y ${mm(y)} Z ${mm(z)} mm`;
    $("position").dataset.x = x; $("position").dataset.y = y; $("position").dataset.z = z;
    if (head) { head.setAttribute("cx", x); head.setAttribute("cy", -y); }
  }
  if ("activity" in e) showActivity(e.activity);
}

function showActivity(a) {
  activity = a;
  $("activity").textContent = a ? `(${a})` : "";
  const free = !a;
  $("start").disabled = !(free && plan);
  $("plan").disabled = !upload;
  for (const id of ["home", "unlock", "set-feed"]) $(id).disabled = !free;
  for (const b of document.querySelectorAll(".jog")) b.disabled = !(free || a === "jog");
}

function showProgress(p) {
  if (!p) { $("progress").textContent = "no job running"; return; }
  $("bar").value = p.confirmed / Math.max(p.total, 1);
  $("progress").textContent = `${p.name}: ${p.confirmed} of ${p.total} ${p.unit} ` +
    `(${p.percent.toFixed(0)} %), ETA ${p.eta || "?"}`;
}

function showPrompt(p) {
  const dialog = $("prompt");
  prompt = p;
  if (!p) { if (dialog.open) dialog.close(); return; }
  $("prompt-text").textContent = p.kind === "pen" ? `${p.text}, then press Done` : p.text;
  $("prompt-yes").textContent = p.kind === "pen" ? "Done" : "Yes, it is there";
  $("prompt-no").textContent = p.kind === "pen" ? "Stop the job" : "No";
  if (!dialog.open) dialog.show();     // not modal: the stop button stays in reach
}

function showResumable(name) {
  $("resume").disabled = !name;
  $("resume").title = name ? `continue the stopped job of ${name}` : "";
}

function showHistory(rows) {
  const body = $("history");
  body.textContent = "";
  for (const r of rows.slice().reverse()) {
    const tr = document.createElement("tr");
    const time = r.elapsed_s === null ? "" : `${r.elapsed_s} s`;
    for (const text of [r.file, r.started.replace("T", " ").slice(0, 19), time, r.result]) {
      const td = document.createElement("td"); td.textContent = text; tr.append(td);
    }
    body.append(tr);
  }
}

let history = [];
function connect() {
  const events = new EventSource("/api/events");
  events.addEventListener("state", (m) => {
    const s = JSON.parse(m.data);
    showStatus(s); showProgress(s.job); showPrompt(s.prompt); showResumable(s.resumable);
    history = s.history; showHistory(history);
    if (!$("feed").value) $("feed").value = s.feed_mm_s;
  });
  events.addEventListener("status", (m) => showStatus(JSON.parse(m.data)));
  events.addEventListener("progress", (m) => showProgress(JSON.parse(m.data)));
  events.addEventListener("prompt", (m) => showPrompt(JSON.parse(m.data).prompt));
  events.addEventListener("activity", (m) => showActivity(JSON.parse(m.data).activity));
  events.addEventListener("message", (m) => say(JSON.parse(m.data).text));
  events.addEventListener("failure", (m) => say(JSON.parse(m.data).text, true));
  events.addEventListener("job", (m) => {
    const job = JSON.parse(m.data).job;
    history = history.filter((r) => r.id !== job.id || r.started !== job.started).concat([job]);
    showHistory(history);
    if (job.result !== "running") api("/api/state").then((s) => showResumable(s.resumable));
  });
  // the browser's own error event: the stream broke (it connects again by itself)
  events.onerror = () => { $("state").textContent = "no server?"; };
}

$("upload").addEventListener("change", async () => {
  const file = $("upload").files[0];
  if (!file) return;
  const response = await fetch("/api/uploads", {method: "POST", body: file,
    headers: {"x-filename": encodeURIComponent(file.name)}});
  const data = await response.json();
  if (!response.ok) { say(data.error, true); return; }
  upload = data; plan = null;
  $("upload-info").textContent = `${data.name}: ${data.kind}` +
    (data.sides.length ? `, sides ${data.sides.join(" and ")}` : "");
  $("side").disabled = data.kind !== "board";
  showActivity(activity);
});

$("plan").addEventListener("click", async () => {
  $("plan").disabled = true;
  $("plan-lines").textContent = "planning ...";
  try {
    plan = await api("/api/plans", {upload: upload.id, pens: $("pens").value,
      mode: $("mode").value, side: $("side").value, offset: $("offset").value,
      allow_open: $("allow-open").checked, mill: $("mill").value});
  } catch (e) { plan = null; $("plan-lines").textContent = ""; showActivity(activity); return; }
  $("plan-lines").textContent = "";
  const counts = plan.mill ? `${plan.commands} G-code lines, ${plan.pen_changes} pauses (M0)`
    : `${plan.commands} commands, ${plan.pen_changes} pen changes`;
  for (const line of [...plan.lines, counts]) {
    const li = document.createElement("li"); li.textContent = line; $("plan-lines").append(li);
  }
  if (!plan.preview) {                // a mill job: its G-code is its plan, no preview
    $("preview").textContent = ""; head = null; showActivity(activity); return;
  }
  const svg = await (await fetch(plan.preview)).text();
  const box = $("preview");
  box.innerHTML = svg.replace(/^<\?xml[^>]*>\s*/, "");
  const root = box.querySelector("svg");
  root.removeAttribute("width"); root.removeAttribute("height");
  const view = root.viewBox.baseVal;
  head = document.createElementNS("http://www.w3.org/2000/svg", "circle");
  head.setAttribute("id", "head");
  head.setAttribute("r", Math.max(view.width, view.height) / 60);
  head.setAttribute("fill", "#e53935"); head.setAttribute("fill-opacity", "0.8");
  const p = $("position").dataset;
  head.setAttribute("cx", p.x || 0); head.setAttribute("cy", -(p.y || 0));
  root.append(head);
  showActivity(activity);
});

$("start").addEventListener("click", () => plan && api("/api/jobs", {plan: plan.id}));
$("stop").addEventListener("click", () => api("/api/stop", {}));
$("resume").addEventListener("click", () => api("/api/resume", {}));
$("home").addEventListener("click", () => api("/api/home", {}));
$("unlock").addEventListener("click", () => api("/api/unlock", {}));
$("set-feed").addEventListener("click", () => api("/api/feed", {mm_s: Number($("feed").value)}));
$("prompt-yes").addEventListener("click", () => prompt && api("/api/prompt", {id: prompt.id, answer: true}));
$("prompt-no").addEventListener("click", () => {
  if (!prompt) return;
  if (prompt.kind === "pen") api("/api/stop", {}); else api("/api/prompt", {id: prompt.id, answer: false});
});

// Jog: a step of the chosen distance, or held: the request stays open while the button
// is pressed; letting go (or leaving the page) closes it, and the server stops the head.
for (const button of document.querySelectorAll(".jog")) {
  let held = null;
  const body = () => ({axis: button.dataset.axis, direction: Number(button.dataset.dir)});
  const release = () => {
    if (held) { held.abort(); held = null; button.classList.remove("held"); }
  };
  button.addEventListener("pointerdown", async (e) => {
    e.preventDefault();
    const step = $("step").value;
    if (step) { api("/api/jog", {...body(), distance_mm: Number(step)}); return; }
    button.setPointerCapture(e.pointerId);
    held = new AbortController();
    button.classList.add("held");
    const signal = held.signal;
    try {
      const response = await fetch("/api/jog", {method: "POST", signal, body: JSON.stringify(body()),
        headers: {"content-type": "application/json"}});
      if (!response.ok) { say((await response.json()).error, true); release(); return; }
      const reader = response.body.getReader(), decoder = new TextDecoder();
      let text = "";
      for (;;) {
        const {value, done} = await reader.read();
        if (done) break;
        text += decoder.decode(value, {stream: true});
        const lines = text.split("\n"); text = lines.pop();
        for (const line of lines) {
          const e = JSON.parse(line);
          if (e.position) showStatus({state: "jog", position: e.position});
          if (e.said) e.said.forEach((t) => say(t));
        }
      }
    } catch (err) { /* let go: the request was aborted */ }
    release();
  });
  for (const type of ["pointerup", "pointercancel", "lostpointercapture"]) {
    button.addEventListener(type, release);
  }
}

showActivity(null);
connect();
