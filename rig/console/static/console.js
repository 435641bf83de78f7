// The operator console's page: the WebSocket feed (/ws) drawn with uPlot, the plate plan in SVG, the controls.
// window.consoleStats is read by the tests and the benchmark: live frames received and plot redraws.
"use strict";
(function () {
  const WINDOW_S = 15;            // seconds shown in the plots
  const $ = (id) => document.getElementById(id);
  const stats = window.consoleStats = { frames: 0, draws: 0, statuses: 0, detections: 0, lastT: null, hello: 0, planIndex: null, dropped: 0 };
  const live = { header: null, session: null, at: [], aa: [], pt: [], pp: [], detections: [], faults: [] };
  let status = null, controls = false, token = sessionStorage.getItem("operatorToken") || "";
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
    ...plotSize(poseEl), scales: { x: { time: false }, mm: {}, deg: {} }, legend: { live: false },
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
    const waiting = status.state === "waiting for the operator";
    $("prompt").hidden = !waiting; if (waiting) $("prompt").textContent = status.message;
    $("report").hidden = !(status.session && ["done", "faulted"].includes(status.state) && !status.active);
    showRuns();
  }

  function showRuns() {
    const h = live.header, p = status ? status.progress || {} : {}, outcomes = p.outcomes || {};
    const plan = h ? h.plan : [];
    const current = p.run ? p.run.plan_index : null;
    $("runs").innerHTML = plan.map((r) => {
      let s = outcomes[String(r.plan_index)] || (r.plan_index === current && status && status.state === "running" ? "running" : "pending");
      return `<tr class="${r.plan_index === current ? "current" : ""}"><td>${r.plan_index + 1}</td><td>${esc(r.record)}</td>` +
             `<td>${fmt(r.angle_deg, 1)}°</td><td class="st-${s}">${s}</td></tr>`;
    }).join("");
  }

  function esc(s) { return String(s).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c])); }

  function showPlate() {
    const svg = $("plate"), h = live.header;
    if (!h) { svg.innerHTML = ""; return; }
    const bodies = h.bodies;
    const ext = Math.max(0.4, ...bodies.map((b) => Math.max(Math.abs(b.x) + b.b, Math.abs(b.y) + b.depth))) * 1.35;
    svg.setAttribute("viewBox", `${-ext} ${-ext} ${2 * ext} ${2 * ext}`);
    const fell = {};
    for (const d of live.detections) fell[d.body_id] = d;
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
    $("detections").innerHTML = live.detections.map((d) => `<li class="detection">body ${d.body_id} fell to the ` +
      `${d.direction > 0 ? "low" : d.direction < 0 ? "high" : "no"} side at ${fmt(d.t, 2)} s</li>`).join("");
  }

  function showFaults() {
    $("faults").innerHTML = live.faults.length ? live.faults.slice(-20).map((f) =>
      `<li>${fmt(f.t, 2)} s · ${esc(f.name)} · ${esc(f.detail)}</li>`).join("") : `<li class="none">none</li>`;
  }

  // ----- the feed ------------------------------------------------------------------------------------
  function newRun(header, session) {
    const changed = !live.header || session !== live.session || header.plan_index !== live.header.plan_index;
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
        live.faults = m.faults || [];
        if (m.header) { live.header = null; newRun(m.header, m.session); }
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
  function showControls() {
    const unlocked = controls && !!token;
    for (const id of ["pause", "resume", "abort"]) $(id).disabled = !unlocked;
    $("estop").classList.toggle("locked", !unlocked);
    const mode = $("control-mode");
    mode.textContent = !controls ? "read-only: this console has no rig key" : unlocked ? "controls unlocked (this browser session)" : "read-only: enter the operator token";
    mode.className = "mode" + (unlocked ? " unlocked" : "");
  }

  function reply(text, ok) { const r = $("control-reply"); r.textContent = text; r.className = "reply " + (ok ? "ok" : "bad"); }

  async function post(path) {
    const response = await fetch(path, { method: "POST", headers: { "Content-Type": "application/json", "X-Operator-Token": token }, body: "{}" });
    let body; try { body = await response.json(); } catch (e) { body = { ok: false, message: `HTTP ${response.status}` }; }
    return { ok: response.ok && body.ok, message: body.message };
  }

  async function send(command) {
    if (!token) { reply("enter the operator token first (rig service token prints it)", false); $("token").focus(); return; }
    const r = await post(`/api/control/${command}`);
    reply(r.message, r.ok);
  }

  $("token-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    token = $("token").value.trim();
    const r = await post("/api/token");
    if (r.ok) { sessionStorage.setItem("operatorToken", token); $("token").value = ""; }
    else { token = ""; sessionStorage.removeItem("operatorToken"); }
    reply(r.message, r.ok); showControls();
  });
  $("pause").addEventListener("click", () => send("pause"));
  $("resume").addEventListener("click", () => send("resume"));
  $("abort").addEventListener("click", () => send("abort"));
  $("estop").addEventListener("click", () => send("estop"));
  showControls();
  connect();
})();
