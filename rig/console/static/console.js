// The operator console's page: the WebSocket feed (/ws) drawn with uPlot, the plate plan in SVG, the controls.
// window.consoleStats is read by the tests and the benchmark: live frames received and plot redraws;
// window.consolePlots the two uPlot instances (their scales: the tests).
// Every text from the telemetry is escaped (esc) or set as textContent, every number put in markup goes through
// num; the operator token is never kept: the browser session is an HttpOnly cookie, its CSRF token lives in `csrf`.
"use strict";
(function () {
  const WINDOW_S = 15;            // seconds shown in the plots
  const $ = (id) => document.getElementById(id);
  const stats = window.consoleStats = { frames: 0, draws: 0, statuses: 0, detections: 0, lastT: null, hello: 0, planIndex: null, dropped: 0 };
  const live = { header: null, session: null, at: [], aa: [], pt: [], pp: [], detections: [], faults: [] };
  let status = null, controls = false, csrf = "";
  // The table's limits when the run's header has none (Table IV, tilt 10°); each pose axis spans at least
  // MIN_SPAN of them, so that noise at rest is not drawn as violent motion.
  const DEFAULT_LIMITS = { surge_m: 0.25, sway_m: 0.25, heave_m: 0.18, tilt_deg: 10 };
  const MIN_SPAN = 0.02;
  const limits = () => (live.header && live.header.limits) || DEFAULT_LIMITS;
  const halfSpan = { mm: () => MIN_SPAN * 1000 * Math.max(limits().surge_m, limits().sway_m, limits().heave_m),
                     deg: () => MIN_SPAN * limits().tilt_deg };
  function atLeast(half) {         // a uPlot range: the data's, widened about its middle to ±half() at least
    return (u, lo, hi) => {
      if (lo === null || hi === null || !isFinite(lo) || !isFinite(hi)) return [-half(), half()];
      const mid = (lo + hi) / 2, h = Math.max(0.55 * (hi - lo), half());
      return [mid - h, mid + h];
    };
  }
  let dirty = false, framesThisSecond = 0;

  // ----- plots (uPlot) -----------------------------------------------------------------------------
  const axis = { stroke: "#9fb0c2", grid: { stroke: "#1f2b37", width: 1 }, ticks: { stroke: "#2a3a4b" } };
  function plotSize(el) { return { width: Math.max(300, el.clientWidth), height: 230 }; }
  const accelEl = $("plot-accel"), poseEl = $("plot-pose");
  const accelPlot = new uPlot({
    ...plotSize(accelEl), scales: { x: { time: false } }, legend: { live: false },
    series: [{ label: "t [s]" },
             { label: "measured", stroke: "#4aa8ff", width: 1.8 },
             { label: "commanded", stroke: "#ffd76a", width: 1.4, dash: [5, 4] }],
    axes: [{ ...axis, label: "run time [s]" }, { ...axis, label: "m/s²" }],
  }, [[], [], []], accelEl);
  const posePlot = new uPlot({
    ...plotSize(poseEl), scales: { x: { time: false }, mm: { range: atLeast(halfSpan.mm) },
                                   deg: { range: atLeast(halfSpan.deg) } }, legend: { live: false },
    series: [{ label: "t [s]" },
             { label: "surge [mm]", stroke: "#4aa8ff", width: 1.5, scale: "mm" },
             { label: "sway [mm]", stroke: "#3ddc84", width: 1.5, scale: "mm" },
             { label: "heave [mm]", stroke: "#c58cff", width: 1.5, scale: "mm" },
             { label: "roll [°]", stroke: "#ffd76a", width: 1.2, scale: "deg" },
             { label: "pitch [°]", stroke: "#ff8a3d", width: 1.2, scale: "deg" }],
    axes: [{ ...axis, label: "run time [s]" }, { ...axis, scale: "mm", label: "mm" },
           { ...axis, scale: "deg", side: 1, label: "degrees", grid: { show: false },
             values: (u, ticks) => ticks.map((v) => v.toFixed(Math.max(0, Math.min(4, 1 - Math.floor(Math.log10(Math.abs(ticks[1] - ticks[0]) || 1)))))) }],
  }, [[], [], [], [], [], []], poseEl);
  window.consolePlots = { accel: accelPlot, pose: posePlot };
  window.addEventListener("resize", () => { accelPlot.setSize(plotSize(accelEl)); posePlot.setSize(plotSize(poseEl)); });

  function interp(xs, ys, x) {       // commanded acceleration at time x (linear; null outside the drive)
    if (!xs.length || x < xs[0] || x > xs[xs.length - 1]) return null;
    let lo = 0, hi = xs.length - 1;
    while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (xs[mid] <= x) lo = mid; else hi = mid; }
    const f = xs[hi] === xs[lo] ? 0 : (x - xs[lo]) / (xs[hi] - xs[lo]);
    return ys[lo] + f * (ys[hi] - ys[lo]);
  }

  function trim(ts, vs, now) { let k = 0; while (k < ts.length && ts[k] < now - WINDOW_S) k++; if (k) { ts.splice(0, k); vs.splice(0, k); } }

  function draw() {
    requestAnimationFrame(draw);
    if (!dirty) return;
    dirty = false;
    const now = Math.max(live.at.length ? live.at[live.at.length - 1] : -Infinity, live.pt.length ? live.pt[live.pt.length - 1] : -Infinity);
    if (!isFinite(now)) return;
    trim(live.at, live.aa, now); trim(live.pt, live.pp, now);
    const cmd = live.header ? live.header.commanded : { t: [], a: [] };
    accelPlot.setData([live.at.slice(), live.aa.slice(), live.at.map((t) => interp(cmd.t, cmd.a, t))]);
    const mm = (i) => live.pp.map((p) => p[i] * 1000), deg = (i) => live.pp.map((p) => p[i] * 180 / Math.PI);
    posePlot.setData([live.pt.slice(), mm(0), mm(1), mm(2), deg(3), deg(4)]);
    stats.draws++; stats.lastT = now;
  }
  requestAnimationFrame(draw);
  setInterval(() => { $("fps").textContent = framesThisSecond; framesThisSecond = 0; }, 1000);

  // ----- the run, the plate, the runs ----------------------------------------------------------------
  const fmt = (x, d = 2) => (x === null || x === undefined || !isFinite(x)) ? "–" : Number(x).toFixed(d);
  const duration = (s) => (s === null || !isFinite(s)) ? "–" : (s >= 60 ? `${Math.floor(s / 60)} min ${Math.round(s % 60)} s` : `${s.toFixed(1)} s`);

  function showStatus() {
    if (!status) return;
    const p = status.progress || {}, h = live.header;
    const st = $("state"), key = (status.state || "idle").split(" ")[0];
    st.textContent = status.state; st.className = "state " + key; st.dataset.state = status.state;
    $("session").textContent = status.session || "no session";
    $("message").textContent = status.message || "–";
    const run = p.run;
    $("run-index").textContent = run ? `${run.plan_index + 1} of ${p.runs_total}` : "–";
    $("run-record").textContent = h && run && h.plan_index === run.plan_index ? h.record : (run ? run.record : "–");
    $("run-angle").textContent = run ? `${fmt(run.angle_deg, 1)}°` : "–";
    $("run-scale").textContent = h && run && h.plan_index === run.plan_index ? fmt(h.scale_factor, 3) : "–";
    $("table-state").textContent = p.table_state || "–";
    $("peak").textContent = p.peak_accel === null || p.peak_accel === undefined ? "–" : `${fmt(p.peak_accel / 9.81, 3)} g`;
    $("runs-done").textContent = `${p.runs_done ?? 0} / ${p.runs_total ?? 0}`;
    const frac = p.samples_total ? p.samples_sent / p.samples_total : 0;
    $("run-progress").style.width = `${Math.round(100 * frac)}%`;
    const rate = h ? h.rate : null;
    const runLeft = rate && p.samples_total ? (p.samples_total - p.samples_sent) / rate : null;
    const active = status.active && !["done", "faulted"].includes(status.state);
    $("run-left").textContent = active && runLeft !== null ? duration(runLeft) : "–";
    $("session-left").textContent = active && h && runLeft !== null ? duration(runLeft + h.table_seconds_after) : "–";
    $("report").hidden = !(status.session && ["done", "faulted"].includes(status.state) && !status.active);
    showPrompt(); showQueue(); showRuns(); showControls();
  }

  function showRuns() {
    const h = live.header, p = status ? status.progress || {} : {}, outcomes = p.outcomes || {};
    const plan = h && Array.isArray(h.plan) ? h.plan : [];
    const current = p.run ? p.run.plan_index : null;
    $("runs").innerHTML = plan.map((r) => {
      const s = String(outcomes[String(r.plan_index)] || (r.plan_index === current && status && status.state === "running" ? "running" : "pending"));
      const faults = live.faults.filter((f) => f.plan_index === r.plan_index).length;
      return `<tr class="${r.plan_index === current ? "current" : ""}"><td>${num(r.plan_index) + 1}</td><td>${esc(r.record)}</td>` +
             `<td>${fmt(r.angle_deg, 1)}°</td><td class="st-${cls(s)}">${esc(s)}</td><td>${faults || ""}</td></tr>`;
    }).join("");
  }

  // The operator's prompt (an attended session waiting): its text, for "which fell" a choice per body, the answers.
  let promptShown = null;
  function showPrompt() {
    const prompt = status && status.state === "waiting for the operator" ? status.prompt || null : null;
    const waiting = status && status.state === "waiting for the operator";
    $("prompt-box").hidden = !waiting;
    if (!waiting) { promptShown = null; return; }
    $("prompt").textContent = prompt ? prompt.text : status.message;
    const id = prompt ? prompt.id : null;
    if (id !== promptShown) {      // redrawn only for a new prompt: the operator's choices stay as set
      promptShown = id;
      const bodies = prompt && prompt.kind === "which_fell" && Array.isArray(prompt.bodies) ? prompt.bodies : [];
      $("prompt-bodies").innerHTML = bodies.map((b) => `<label for="fell-${num(b.body_id)}">${esc(b.name)} (body ${num(b.body_id)})</label>` +
        `<select id="fell-${num(b.body_id)}" data-body="${num(b.body_id)}"><option value="0">standing</option>` +
        `<option value="1">fell to the low side</option><option value="-1">fell to the high side</option></select>`).join("");
    }
  }

  function showQueue() {
    const queue = status && Array.isArray(status.queue) ? status.queue : [];
    const idle = !status || !status.active;
    $("queue").innerHTML = queue.length ? queue.map((q) => `<li><button class="start" data-queued="${num(q.id)}"` +
      `${idle && unlocked() ? "" : " disabled"}>Start</button> ${num(q.id)} · ${esc(q.name)}` +
      `${q.emulate ? " · emulated table" : ""}${q.attended ? " · attended" : ""}</li>`).join("") : `<li class="none">none</li>`;
  }

  function esc(s) { return String(s).replace(/[&<>"'`]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;", "`": "&#96;" }[c])); }
  function num(x) { const n = Number(x); return isFinite(n) ? n : 0; }          // a number for markup, never text
  function cls(s) { return String(s).replace(/[^a-z-]/g, ""); }                  // a class name: letters and '-' only

  function showPlate() {
    const svg = $("plate"), h = live.header;
    if (!h) { svg.innerHTML = ""; return; }
    const bodies = (Array.isArray(h.bodies) ? h.bodies : []).map((b) => ({ body_id: num(b.body_id), name: b.name, x: num(b.x), y: num(b.y), b: num(b.b), h: num(b.h), depth: num(b.depth) }));
    const ext = Math.max(0.4, ...bodies.map((b) => Math.max(Math.abs(b.x) + b.b, Math.abs(b.y) + b.depth))) * 1.35;
    svg.setAttribute("viewBox", `${-ext} ${-ext} ${2 * ext} ${2 * ext}`);
    const fell = {};
    for (const d of live.detections) fell[num(d.body_id)] = { direction: Math.sign(num(d.direction)), t: d.t };
    // plan view: x (fall line, +downhill) to the right, y up; the low side is on the right
    let out = `<rect x="${-ext * 0.92}" y="${-ext * 0.8}" width="${ext * 1.84}" height="${ext * 1.6}" rx="${ext * 0.03}" fill="#16212c" stroke="#3b5068" stroke-width="${ext * 0.01}"/>`;
    out += `<text x="${ext * 0.88}" y="${-ext * 0.85}" text-anchor="end" font-size="${ext * 0.08}" fill="#3d9bff">low side ▶ (+x downhill)</text>`;
    out += `<text x="${-ext * 0.88}" y="${-ext * 0.85}" font-size="${ext * 0.08}" fill="#ff8a3d">◀ high side</text>`;
    out += `<text x="0" y="${ext * 0.95}" text-anchor="middle" font-size="${ext * 0.07}" fill="#7d8ea1">β = ${live.header ? fmt(live.header.angle_deg, 1) : "–"}°</text>`;
    for (const b of bodies) {
      const d = fell[b.body_id];
      const colour = !d ? "#3ddc84" : d.direction > 0 ? "#3d9bff" : d.direction < 0 ? "#ff8a3d" : "#3ddc84";
      const cx = b.x, cy = -b.y;
      out += `<g class="body" data-body="${b.body_id}" data-fell="${d ? d.direction : 0}">`;
      if (d && d.direction !== 0) {   // the body lying on its side, towards where it fell
        const len = Math.min(b.h, ext * 0.5), x0 = d.direction > 0 ? cx : cx - len;
        out += `<rect x="${x0}" y="${cy - b.depth / 2}" width="${len}" height="${b.depth}" fill="${colour}" opacity="0.85"/>`;
      } else {
        out += `<rect x="${cx - b.b / 2}" y="${cy - b.depth / 2}" width="${b.b}" height="${b.depth}" fill="${colour}"/>`;
      }
      const label = d ? `${esc(b.name)} · ${d.direction > 0 ? "low" : "high"} side · ${fmt(d.t, 2)} s` : `${esc(b.name)} · standing`;
      out += `<text x="${cx}" y="${cy + b.depth / 2 + ext * 0.09}" text-anchor="middle" font-size="${ext * 0.07}" fill="#d8e2ec">${label}</text></g>`;
    }
    svg.innerHTML = out;
    $("detections").innerHTML = live.detections.map((d) => `<li class="detection">body ${num(d.body_id)} fell to the ` +
      `${d.direction > 0 ? "low" : d.direction < 0 ? "high" : "no"} side at ${fmt(d.t, 2)} s</li>`).join("");
  }

  // The session's faults, each under the run it happened in (newest last).
  function showFaults() {
    $("faults").innerHTML = live.faults.length ? live.faults.slice(-20).map((f) =>
      `<li data-run="${f.plan_index === null || f.plan_index === undefined ? "" : num(f.plan_index)}">` +
      `${f.plan_index === null || f.plan_index === undefined ? "between runs" : `run ${num(f.plan_index) + 1}`} · ` +
      `${fmt(f.t, 2)} s · ${esc(f.name)} · ${esc(f.detail)}</li>`).join("") : `<li class="none">none</li>`;
    showRuns();
  }

  // ----- the feed ------------------------------------------------------------------------------------
  function newRun(header, session) {
    const changed = !live.header || session !== live.session || header.plan_index !== live.header.plan_index;
    if (session !== live.session) live.faults = [];       // a new session: its own faults only
    live.header = header; live.session = session; stats.planIndex = header.plan_index;
    if (changed) { live.at = []; live.aa = []; live.pt = []; live.pp = []; live.detections = []; stats.lastT = null; }
  }

  function onLive(m) {
    stats.frames++; framesThisSecond++;
    if (m.header) newRun(m.header, m.session);
    if (m.accel) { live.at.push(...m.accel.t); live.aa.push(...m.accel.a); }
    if (m.pose) { live.pt.push(...m.pose.t); live.pp.push(...m.pose.p); }
    if (m.detections && m.detections.length) { live.detections.push(...m.detections); stats.detections += m.detections.length; }
    if (m.faults && m.faults.length) { live.faults.push(...m.faults); showFaults(); }
    dirty = true;
    if (m.header || (m.detections && m.detections.length)) { showPlate(); showStatus(); }
  }

  function connect() {
    const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
    ws.onopen = () => { $("conn").textContent = "live"; };
    ws.onclose = () => { $("conn").textContent = "lost: reconnecting"; setTimeout(connect, 1000); };
    ws.onmessage = (event) => {
      const m = JSON.parse(event.data);
      if (m.type === "hello") {
        stats.hello++; controls = m.controls;
        if (m.header) { live.header = null; live.session = m.session; newRun(m.header, m.session); }
        live.faults = m.faults || [];
        live.at = m.accel.t; live.aa = m.accel.a; live.pt = m.pose.t; live.pp = m.pose.p;
        live.detections = m.detections || [];
        status = m.status; dirty = true; showPlate(); showFaults(); showStatus(); showControls();
      } else if (m.type === "status") {
        stats.statuses++; status = m; showStatus();
      } else if (m.type === "live") {
        onLive(m);
      } else if (m.type === "stats") {
        stats.dropped = m.dropped; $("dropped").textContent = m.dropped;
      }
    };
  }

  // ----- controls ------------------------------------------------------------------------------------
  let role = "";                          // the browser session's: "operator" commands, "viewer" watches only
  const unlocked = () => controls && !!csrf && role === "operator";

  // What each button does in each state: a button that would do nothing is disabled. Pause: while a session
  // plays (not yet paused); resume: while paused; abort: while a session is prepared or played; the emergency stop
  // is never disabled (it brakes whatever moves; with nothing running the service says so).
  function enabled(state, active) {
    const playing = active && !["done", "faulted", "idle"].includes(state);
    return { pause: playing && !["paused", "stopping", "starting"].includes(state),
             resume: playing && state === "paused",
             abort: playing && state !== "stopping",
             answer: state === "waiting for the operator" && !!(status && status.prompt) };
  }

  function showControls() {
    const on = unlocked(), state = status ? status.state : "idle", can = enabled(state, !!(status && status.active));
    for (const id of ["pause", "resume", "abort"]) $(id).disabled = !(on && can[id]);
    for (const id of ["answer-done", "answer-decline"]) $(id).disabled = !(on && can.answer);
    $("estop").classList.toggle("locked", !on);
    $("lock").hidden = !csrf; $("token").hidden = !!csrf; $("unlock").hidden = !!csrf;
    const mode = $("control-mode");
    mode.textContent = !controls ? "read-only: this console has no rig key" : on ? "controls unlocked (this browser session)"
      : csrf ? "watching as a viewer: a viewer may not command" : "read-only: enter the operator token";
    mode.className = "mode" + (on ? " unlocked" : "");
  }

  function reply(text, ok) { const r = $("control-reply"); r.textContent = text; r.className = "reply " + (ok ? "ok" : "bad"); }

  async function post(path, body, headers) {
    const response = await fetch(path, { method: "POST", credentials: "same-origin",
      headers: { "Content-Type": "application/json", ...headers }, body: JSON.stringify(body || {}) });
    let answer; try { answer = await response.json(); } catch (e) { answer = { ok: false, message: `HTTP ${response.status}` }; }
    return { ok: response.ok && answer.ok, message: answer.message, body: answer, status: response.status };
  }

  async function send(command, body) {
    if (!csrf) { reply("enter the operator token first (rig service token prints it)", false); $("token").focus(); return; }
    const r = await post(`/api/control/${command}`, body, { "X-Console-CSRF": csrf });
    if (r.status === 403 && !r.ok && role === "operator") { csrf = ""; showControls(); }   // the session expired or was ended elsewhere
    reply(r.message, r.ok);
  }

  async function restoreSession() {     // a reloaded page: the browser session's cookie is still there
    try {
      const response = await fetch("/api/session", { credentials: "same-origin" });
      const body = await response.json();
      csrf = body.unlocked ? body.csrf : ""; role = body.unlocked ? body.role : "";
    } catch (e) { csrf = ""; role = ""; }
    showControls(); showQueue();
  }

  $("token-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    const given = $("token").value.trim();
    $("token").value = "";
    const r = await post("/api/token", {}, { "X-Operator-Token": given });
    csrf = r.ok ? r.body.csrf : ""; role = r.ok ? r.body.role : "";
    reply(r.message, r.ok); showControls(); showQueue();
  });
  $("lock").addEventListener("click", async () => {
    const r = await post("/api/lock", {}, { "X-Console-CSRF": csrf });
    csrf = ""; reply(r.message, r.ok); showControls(); showQueue();
  });
  $("pause").addEventListener("click", () => send("pause"));
  $("resume").addEventListener("click", () => send("resume"));
  $("abort").addEventListener("click", () => send("abort"));
  $("estop").addEventListener("click", () => send("estop"));
  $("queue").addEventListener("click", (event) => {
    const button = event.target.closest("button.start");
    if (button && !button.disabled) send("start", { queued: Number(button.dataset.queued) });
  });
  function answer(reply) {
    const prompt = status && status.prompt;
    if (!prompt) return;
    const fell = [];
    for (const select of document.querySelectorAll("#prompt-bodies select")) {
      const direction = Number(select.value);
      if (direction !== 0) fell.push([Number(select.dataset.body), direction]);
    }
    send("answer", { prompt: prompt.id, reply, fell: reply === "done" ? fell : [] });
  }
  $("answer-done").addEventListener("click", () => answer("done"));
  $("answer-decline").addEventListener("click", () => answer("decline"));
  showControls();
  restoreSession();
  connect();
})();
