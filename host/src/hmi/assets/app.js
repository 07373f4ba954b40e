// The ratf operator's page: draws the floor and the robot from the server's stream, and
// sends the controls with the token from this page's URL (?token=…). No build step.
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const token = new URLSearchParams(location.search).get("token") || "";
  const COLORS = { R: "#d03030", G: "#30a040", B: "#3060d0", "?": "#888" };
  const VIEW = { x0: -0.95, x1: 0.95, y0: -0.75, y1: 0.75 };
  const state = { floor: null, info: null, last: null, picking: null, drag: null };
  window.ratf = state;

  const canvas = $("map");
  const ctx = canvas.getContext("2d");
  let scale = 1, cssWidth = 1;

  function fit() {
    const ratio = window.devicePixelRatio || 1;
    cssWidth = canvas.clientWidth || 1;
    const cssHeight = cssWidth * (VIEW.y1 - VIEW.y0) / (VIEW.x1 - VIEW.x0);
    canvas.width = Math.round(cssWidth * ratio);
    canvas.height = Math.round(cssHeight * ratio);
    scale = canvas.width / (VIEW.x1 - VIEW.x0);
    draw();
  }
  const px = (x, y) => [(x - VIEW.x0) * scale, (VIEW.y1 - y) * scale];
  const font = () => Math.max(11, Math.round(cssWidth / 55)) * (canvas.width / cssWidth);

  function rect(b, fill, stroke) {
    const [x, y] = px(b[0], b[3]);
    const w = (b[2] - b[0]) * scale, h = (b[3] - b[1]) * scale;
    if (fill) { ctx.fillStyle = fill; ctx.fillRect(x, y, w, h); }
    if (stroke) { ctx.strokeStyle = stroke; ctx.lineWidth = 1; ctx.strokeRect(x, y, w, h); }
  }
  function text(s, x, y, color, size, align) {
    ctx.fillStyle = color; ctx.font = `${size || font()}px sans-serif`;
    ctx.textAlign = align || "center"; ctx.textBaseline = "middle";
    const [u, v] = px(x, y); ctx.fillText(s, u, v);
  }
  function robotOutline(pose, color, dashed, fillAlpha) {
    const [l, w] = state.floor.footprint_m;
    const c = Math.cos(pose.yaw_rad), s = Math.sin(pose.yaw_rad);
    const corners = [[l / 2, w / 2], [-l / 2, w / 2], [-l / 2, -w / 2], [l / 2, -w / 2]]
      .map(([a, b]) => px(pose.x + c * a - s * b, pose.y + s * a + c * b));
    ctx.beginPath(); corners.forEach(([u, v], i) => (i ? ctx.lineTo(u, v) : ctx.moveTo(u, v))); ctx.closePath();
    if (fillAlpha) { ctx.globalAlpha = fillAlpha; ctx.fillStyle = color; ctx.fill(); ctx.globalAlpha = 1; }
    ctx.setLineDash(dashed ? [6, 4] : []); ctx.strokeStyle = color; ctx.lineWidth = 2.5; ctx.stroke(); ctx.setLineDash([]);
    const [u0, v0] = px(pose.x, pose.y), [u1, v1] = px(pose.x + c * l * 0.55, pose.y + s * l * 0.55);
    ctx.beginPath(); ctx.moveTo(u0, v0); ctx.lineTo(u1, v1); ctx.lineWidth = 3; ctx.stroke();
  }
  function ellipse(pose, cov) {
    // 95 % of a 2-D Gaussian lies within 2.45 standard deviations (chi-square, 2 dof).
    const [a, b, d] = cov, tr = a + d, det = a * d - b * b;
    const disc = Math.sqrt(Math.max(0, tr * tr / 4 - det));
    const l1 = tr / 2 + disc, l2 = Math.max(0, tr / 2 - disc);
    const angle = Math.atan2(l1 - a, b || 1e-12);
    const k = 2.45, [u, v] = px(pose.x, pose.y);
    const r1 = Math.max(2, k * Math.sqrt(l1) * scale), r2 = Math.max(2, k * Math.sqrt(l2) * scale);
    ctx.beginPath(); ctx.ellipse(u, v, r1, r2, -(b === 0 ? (a >= d ? 0 : Math.PI / 2) : angle), 0, 2 * Math.PI);
    ctx.fillStyle = "rgba(224,123,0,0.15)"; ctx.fill(); ctx.strokeStyle = "#e07b00"; ctx.lineWidth = 1.5; ctx.stroke();
  }
  function scaleBar() {
    const [u, v] = px(-0.70, VIEW.y0 + 0.04), len = 0.2 * scale;
    ctx.strokeStyle = "#222"; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.moveTo(u, v); ctx.lineTo(u + len, v); ctx.moveTo(u, v - 5); ctx.lineTo(u, v + 5);
    ctx.moveTo(u + len / 2, v - 3); ctx.lineTo(u + len / 2, v + 3); ctx.moveTo(u + len, v - 5); ctx.lineTo(u + len, v + 5); ctx.stroke();
    ctx.fillStyle = "#222"; ctx.font = `${font()}px sans-serif`; ctx.textAlign = "left"; ctx.textBaseline = "bottom";
    ctx.fillText("20 cm", u + len + 6, v + font() / 2);
  }

  function draw() {
    const f = state.floor; if (!f) return;
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    rect(f.printed, "#fafafa", "#999");
    rect(f.start, "#e3f5e1", "#8bc48a");
    text("start", (f.start[0] + f.start[2]) / 2, f.start[1] + 0.03, "#4a8a49", font() * 0.9);
    for (const o of f.obstacles) rect(o, "#555", "#333");
    for (const s of f.slots) {
      rect(s.rect, null, "#aaa");
      // Machine slots are small: "in"/"out" there, the machine's name is beside the block.
      const label = /^[AB]\d /.test(s.label) ? s.label.split(" ")[1] : s.label;
      text(label, (s.rect[0] + s.rect[2]) / 2, (s.rect[1] + s.rect[3]) / 2, "#555", font() * 0.8);
    }
    for (const a of f.areas) {
      const below = a.rect[1] > 0 ? a.rect[3] + 0.035 : a.rect[1] - 0.035;
      text(a.label, (a.rect[0] + a.rect[2]) / 2, below, "#1f2a36", font());
    }
    for (const m of f.markers) {
      const [u, v] = px(m.at[0], m.at[1]); ctx.fillStyle = "#777"; ctx.fillRect(u - 3, v - 3, 6, 6);
    }
    if ($("show-graph").checked) {
      const at = {}; for (const w of f.waypoints) at[w.id] = w.at;
      ctx.strokeStyle = "rgba(100,100,200,0.5)"; ctx.lineWidth = 1; ctx.beginPath();
      for (const [a, b] of f.edges) { if (!at[a] || !at[b]) continue; const p = px(...at[a]), q = px(...at[b]); ctx.moveTo(...p); ctx.lineTo(...q); }
      ctx.stroke();
      for (const w of f.waypoints) text(String(w.id), w.at[0], w.at[1], "#5050b0", font() * 0.7);
    }
    const s = state.last;
    for (const b of f.beacons) {
      const [u, v] = px(b.at[0], b.at[1]);
      const seen = s && s.beacons.seen[b.index];
      ctx.beginPath(); ctx.arc(u, v, Math.max(5, b.radius_m * scale), 0, 2 * Math.PI);
      ctx.fillStyle = "#f2c14e"; ctx.fill(); ctx.lineWidth = seen ? 4 : 1.5; ctx.strokeStyle = seen ? "#2f855a" : "#9a7412"; ctx.stroke();
      const out = b.radius_m + 0.03;
      text("B" + b.index, b.at[0], b.at[1] + (b.at[1] > 0 ? out : -out), "#9a7412", font() * 0.9);
    }
    scaleBar();
    if (!s) return;
    for (const p of s.parts) {
      const [u, v] = px(p.at[0], p.at[1]), h = 0.03 * scale;
      ctx.fillStyle = COLORS[p.color] || "#888"; ctx.fillRect(u - h, v - h, 2 * h, 2 * h);
      ctx.strokeStyle = "#222"; ctx.lineWidth = 1; ctx.strokeRect(u - h, v - h, 2 * h, 2 * h);
    }
    ctx.fillStyle = "#d33";
    const dot = Math.max(2, canvas.width / 400);
    for (const [x, y] of s.scan) { const [u, v] = px(x, y); ctx.fillRect(u - dot / 2, v - dot / 2, dot, dot); }
    if (s.target) {
      const route = s.path.length >= 2 ? s.path : [[s.pose.x, s.pose.y], s.target.at];
      ctx.strokeStyle = "#8a2be2"; ctx.lineWidth = 2.5; ctx.setLineDash([8, 5]); ctx.beginPath();
      route.forEach(([x, y], i) => { const [u, v] = px(x, y); if (i) ctx.lineTo(u, v); else ctx.moveTo(u, v); });
      ctx.stroke(); ctx.setLineDash([]);
      const [u1, v1] = px(s.target.at[0], s.target.at[1]);
      ctx.beginPath(); ctx.arc(u1, v1, 9, 0, 2 * Math.PI); ctx.stroke();
    }
    if (s.truth) robotOutline(s.truth, "#1f4e9c", true, 0);
    ellipse(s.pose, s.covariance_m2);
    robotOutline(s.pose, "#e07b00", false, 0.12);
    if (s.carrying) {
      const c = Math.cos(s.pose.yaw_rad), sn = Math.sin(s.pose.yaw_rad), d = state.floor.footprint_m[0] / 2 + 0.03;
      const [u, v] = px(s.pose.x + c * d, s.pose.y + sn * d), h = 0.03 * scale;
      ctx.fillStyle = COLORS[s.carrying] || "#888"; ctx.fillRect(u - h, v - h, 2 * h, 2 * h);
    }
    if (state.drag) {
      const [u, v] = px(state.drag.x, state.drag.y), [u1, v1] = px(state.drag.x + 0.15 * Math.cos(state.drag.yaw), state.drag.y + 0.15 * Math.sin(state.drag.yaw));
      ctx.strokeStyle = "#b7791f"; ctx.lineWidth = 4; ctx.beginPath(); ctx.moveTo(u, v); ctx.lineTo(u1, v1); ctx.stroke();
    }
  }

  const PHASES = { waiting_for_part_list: "waiting for the part list", running: "running", finished: "finished" };
  const fmt = (x, n) => (x === null || x === undefined ? "–" : Number(x).toFixed(n));
  function row(box, name, value, cls) {
    const a = document.createElement("span"); a.textContent = name;
    const b = document.createElement("span"); b.textContent = value; if (cls) b.className = cls;
    box.append(a, b);
  }

  function render(s) {
    state.last = s;
    let phase = PHASES[s.phase] || s.phase;
    if (s.stopped) phase = "STOPPED (" + phase + ")"; else if (s.manual) phase = "manual (" + phase + ")";
    $("phase").textContent = phase;
    $("clock").textContent = s.clock_s === null ? "–" : fmt(s.clock_s, 1) + " s";
    $("placed").textContent = s.placed;
    $("points").textContent = s.points === null ? "–" : s.points;
    $("points-box").hidden = s.points === null;
    $("time").textContent = fmt(s.time_s, 2) + " s";
    if (s.round) {
      $("mode").textContent = `simulator · round ${s.round[0]} · seed ${s.round[1]}`;
      if (document.activeElement !== $("round") && document.activeElement !== $("seed") && state.shownRound !== s.round.join()) {
        state.shownRound = s.round.join(); $("round").value = String(s.round[0]); $("seed").value = String(s.round[1]);
      }
    }
    $("legend-truth").hidden = !s.truth;
    $("pose").textContent = `estimate x ${fmt(s.pose.x, 3)} m, y ${fmt(s.pose.y, 3)} m, ${fmt(s.pose.yaw_rad * 180 / Math.PI, 1)}°` +
      (s.truth ? `; true x ${fmt(s.truth.x, 3)}, y ${fmt(s.truth.y, 3)}` : "");
    const robot = $("robot"); robot.replaceChildren();
    row(robot, "target", s.target ? `${s.target.what} at ${s.target.name}` : "–");
    row(robot, "carrying", s.carrying ? { R: "red", G: "green", B: "blue" }[s.carrying] || "unknown part" : "nothing");
    row(robot, "magnet / switch", `${s.magnet ? "on" : "off"} / ${s.switch_pressed ? "pressed" : "open"}`);
    row(robot, "position σ", `${fmt(Math.sqrt(Math.max(s.covariance_m2[0], s.covariance_m2[2])) * 1000, 1)} mm, heading ${fmt(s.heading_std_rad * 180 / Math.PI, 2)}°`);
    const wheels = $("wheels"); wheels.replaceChildren();
    const names = ["back right", "back left", "front right", "front left"];
    const top = Math.max(10, ...s.wheels.reference_rad_s.map(Math.abs), ...s.wheels.measured_rad_s.map(Math.abs));
    const head = document.createElement("tr"); head.innerHTML = "<td>wheel</td><td>ref / meas rad/s</td><td><i class='sw est'></i>ref <i class='sw truth'></i>meas</td>"; wheels.append(head);
    s.wheels.reference_rad_s.forEach((r, i) => {
      const m = s.wheels.measured_rad_s[i], tr = document.createElement("tr");
      const bar = (v, cls) => { const w = Math.abs(v) / top * 50; return `<i class="${cls}" style="left:${v < 0 ? 50 - w : 50}%;width:${w}%"></i>`; };
      tr.innerHTML = `<td>${names[i]}</td><td>${fmt(r, 1)} / ${fmt(m, 1)}</td><td><div class="bar">${bar(r, "ref")}${bar(m, "meas")}<b></b></div></td>`;
      wheels.append(tr);
    });
    const h = s.health, health = $("health"); health.replaceChildren();
    const rate = (v, want) => [fmt(v, 1) + " /s", s.mode === "replay" || v >= want ? "good" : "poor"];
    row(health, "Mega telemetry", ...rate(h.wheel_hz, 40));
    row(health, "lidar scans", ...rate(h.scan_hz, 5));
    row(health, "IMU", h.imu_hz > 0 ? fmt(h.imu_hz, 0) + " /s" : "none");
    row(health, "beacons (last scan)", `${s.beacons.used} used, ${s.beacons.gated} gated, ${s.beacons.rejected} rejected, ${s.beacons.unseen} unseen`,
      s.beacons.used >= 2 ? "good" : "poor");
    row(health, "localiser", h.lost ? "lost: waiting for three beacons that agree" : "found", h.lost ? "poor" : "good");
    row(health, "scans without beacons", String(h.scans_without_beacons), h.scans_without_beacons > 0 ? "poor" : "");
    row(health, "integrity", `${h.scans_with_dropped_packets} lidar scans with bad packets, ${h.mega_resets} Mega resets`, h.scans_with_dropped_packets ? "poor" : "");
    row(health, "faults", h.faults.length ? h.faults.join("; ") : "none", h.faults.length ? "poor" : "good");
    if (s.replay) {
      const slider = $("slider");
      slider.max = String(s.replay.duration_s);
      if (!state.sliding) slider.value = String(s.time_s);
      $("play").textContent = s.replay.playing ? "❚❚ Pause" : "▶ Play";
      $("replay-time").textContent = `${fmt(s.time_s, 1)} / ${fmt(s.replay.duration_s, 1)} s`;
    } else {
      timeline(s.events, false);
    }
    draw();
  }

  function timeline(lines, jump) {
    const list = $("timeline"); list.replaceChildren();
    for (const e of lines.slice().reverse()) {
      const li = document.createElement("li");
      li.innerHTML = `<span class="t">${fmt(e.t_s, 2)} s</span><span><span class="k k-${e.kind}">${e.kind}</span> </span>`;
      li.lastChild.append(document.createTextNode(e.text));
      if (jump) { li.className = "jump"; li.title = "jump here"; li.onclick = () => send("replay/seek", { t_s: e.t_s }); }
      list.append(li);
    }
  }

  function say(text, ok) { const m = $("message"); m.textContent = text; m.className = ok ? "ok" : "error"; }

  async function send(command, body) {
    try {
      const response = await fetch("/api/" + command, {
        method: "POST",
        headers: Object.assign({ "Content-Type": "application/json" }, token ? { Authorization: "Bearer " + token } : {}),
        body: JSON.stringify(body || {}),
      });
      const answer = await response.json().catch(() => ({}));
      if (response.status === 401) say("refused: " + (answer.error || "no token"), false);
      else if (!response.ok) say(answer.error || "error " + response.status, false);
      else say(answer.message || "sent", true);
    } catch (e) {
      say("the robot does not answer: " + e, false);
    }
  }

  $("force-start").onclick = () => send("force-start", { parts: $("parts").value.trim().toUpperCase() });
  $("stop").onclick = () => send("stop");
  $("resume").onclick = () => send("resume");
  $("restart").onclick = () => send("round", { round: Number($("round").value), seed: Number($("seed").value) });
  $("play").onclick = () => send(state.last && state.last.replay && state.last.replay.playing ? "replay/pause" : "replay/play");
  $("speed").onchange = () => send("replay/speed", { speed: Number($("speed").value) });
  const slider = $("slider");
  slider.addEventListener("input", () => { state.sliding = true; send("replay/seek", { t_s: Number(slider.value) }); });
  slider.addEventListener("change", () => { state.sliding = false; send("replay/seek", { t_s: Number(slider.value) }); });
  $("show-graph").onchange = draw;
  $("set-pose").onclick = () => {
    state.picking = !state.picking; canvas.classList.toggle("picking", state.picking);
    say(state.picking ? "press where the robot stands and drag towards where it faces" : "", true);
  };
  const world = (ev) => {
    const r = canvas.getBoundingClientRect(), k = canvas.width / r.width;
    return { x: (ev.clientX - r.left) * k / scale + VIEW.x0, y: VIEW.y1 - (ev.clientY - r.top) * k / scale };
  };
  canvas.addEventListener("pointerdown", (ev) => { if (!state.picking) return; const p = world(ev); state.drag = { x: p.x, y: p.y, yaw: 0 }; try { canvas.setPointerCapture(ev.pointerId); } catch (e) { /* a pen or mouse without capture */ } draw(); });
  canvas.addEventListener("pointermove", (ev) => { if (!state.drag) return; const p = world(ev); if (Math.hypot(p.x - state.drag.x, p.y - state.drag.y) > 0.02) state.drag.yaw = Math.atan2(p.y - state.drag.y, p.x - state.drag.x); draw(); });
  canvas.addEventListener("pointerup", () => {
    if (!state.drag) return; const d = state.drag; state.drag = null; state.picking = false; canvas.classList.remove("picking");
    send("set-pose", { x: d.x, y: d.y, yaw_deg: d.yaw * 180 / Math.PI }); draw();
  });

  function connect() {
    const events = new EventSource("/api/stream");
    events.onopen = () => { $("link").textContent = "live"; $("link").className = "badge ok"; };
    events.onmessage = (m) => render(JSON.parse(m.data));
    events.onerror = () => { $("link").textContent = "reconnecting"; $("link").className = "badge bad"; };
  }

  async function start() {
    const [floor, info] = await Promise.all([fetch("/api/floor").then((r) => r.json()), fetch("/api/info").then((r) => r.json())]);
    state.floor = floor; state.info = info;
    $("mode").textContent = { sim: "simulator", robot: "robot", replay: "replay" }[info.mode] || info.mode;
    $("access").textContent = token ? "control" : "view only";
    $("access").className = "badge " + (token ? "ok" : "warn");
    $("round-row").hidden = !info.controls.includes("round");
    if (info.round) { $("round").value = String(info.round[0]); $("seed").value = String(info.round[1]); }
    const replay = info.mode === "replay";
    $("replay-box").hidden = !replay;
    for (const id of ["force-start", "stop", "resume", "set-pose", "parts"]) $(id).hidden = replay;
    if (replay) timeline(info.timeline, true);
    fit();
    connect();
  }
  window.addEventListener("resize", fit);
  start().catch((e) => say("the page could not load the floor: " + e, false));
})();
