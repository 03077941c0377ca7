// cordis motion viewer: a hand-written perspective renderer on a 2-D canvas.
// Self-contained on purpose (no library, no network): the page must open offline forever.
// Data: the JSON in #cordis-data, written by crates/cordis-cli/src/render.rs.
(function () {
  "use strict";

  var D = JSON.parse(document.getElementById("cordis-data").textContent);
  // The two motions' names (their file names from `cordis render`), for the legend and the
  // side-by-side panels; pages written before they were stored say what each motion is.
  var LABELS = D.labels || ["trajectory", "compared"];
  var N = D.particles;
  var T = D.frames;
  var DT = D.dt > 0 && isFinite(D.dt) ? D.dt : 1 / 30;

  // Link colours by catalogue index: distinct on a dark background, then golden-angle hues.
  var PALETTE = ["#4cc9f0", "#f72585", "#ffd166", "#06d6a0", "#b197fc", "#ff8c42",
    "#90e0ef", "#ef476f", "#b5e48c", "#f4a3c4", "#48bfe3", "#e9c46a"];
  var GROUP_PALETTE = ["#5eead4", "#fca5a5", "#fde68a", "#a5b4fc", "#f9a8d4", "#bef264",
    "#fdba74", "#7dd3fc"];
  var FREE_COLOUR = "#e6ebf5";
  var FREE_COLOUR_DENSE = "#aab4c8"; // many particles on a mesh: dimmer, so the links show
  var FIXED_COLOUR = "#ffb454";
  // B overlaid on A: one pale shade for every link type, so that the two motions separate.
  var GHOST_COLOUR = "#dfe7f7";
  function paletteColour(list, i) {
    if (i < list.length) return list[i];
    return "hsl(" + Math.round((i * 137.508) % 360) + ", 75%, 65%)";
  }

  // ---- data ---------------------------------------------------------------------------
  // Positions are integers on a grid (step D.quant.step), each frame minus the previous one.
  // They are kept relative to D.quant.origin (the centre of the motion), so Float32 is ample.
  function decode(src) {
    var f = src.frames, q = src.data, M = N * 3;
    var out = new Float32Array(f * M), acc = new Float64Array(M), step = D.quant.step;
    for (var t = 0, k = 0; t < f; t++) {
      for (var j = 0; j < M; j++, k++) {
        acc[j] += q[k];
        out[k] = acc[j] * step;
      }
    }
    return { frames: f, pos: out };
  }
  var A = decode(D.a);
  var B = D.b ? decode(D.b) : null;
  D.a = D.b = null; // let the big arrays go

  var origin = D.quant.origin;
  var types = D.types.map(function (ty, i) {
    var t = { name: ty.name, kind: ty.kind, count: ty.count, colour: paletteColour(PALETTE, i),
      visible: true, drawn: true, note: "" };
    if (ty.segments) t.segments = ty.segments;
    else if (ty.anchors) {
      t.anchors = ty.anchors;
      t.points = new Float32Array(ty.points.length);
      for (var k = 0; k < ty.points.length; k++) t.points[k] = ty.points[k] - origin[k % 3];
    } else if (ty.plane && ty.plane.point && ty.plane.normal) {
      // A contact half-space: drawn as a patch of its surface under the motion.
      t.plane = {
        point: ty.plane.point.map(function (c, k) { return c - origin[k]; }),
        normal: ty.plane.normal, members: ty.plane.members
      };
      t.note = "contact surface";
    } else if (ty.kind === "conditional") {
      t.groups = ty.groups;
      t.range = ty.range;
      if (!(ty.range > 0)) { t.drawn = false; t.note = "no range"; }
      else if (N > 4000) { t.drawn = false; t.note = "not drawn: too many particles"; }
      else t.note = "pairs in range, per frame";
    } else { t.drawn = false; t.note = "acts on velocity, not drawn"; }
    return t;
  });
  var fixed = D.fixed;
  var isFixed = new Uint8Array(N);
  fixed.forEach(function (i) { isFixed[i] = 1; });
  var groupOf = D.groups ? D.groups.of : null;
  var groupNames = D.groups ? D.groups.names : [];
  var totalLinks = types.reduce(function (s, t) { return s + t.count; }, 0);

  // Bounding box of the reference motion A over all frames: it sets the initial view, the
  // floor and the marker sizes. B is left out so that a diverging model does not zoom out.
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (var k = 0; k < A.pos.length; k++) {
    var c = k % 3, v = A.pos[k];
    if (v < lo[c]) lo[c] = v;
    if (v > hi[c]) hi[c] = v;
  }
  var centre = [0, 1, 2].map(function (c) { return 0.5 * (lo[c] + hi[c]); });
  var ext = [0, 1, 2].map(function (c) { return hi[c] - lo[c]; });
  var maxExt = Math.max(ext[0], ext[1], ext[2]);
  var radius = 0.5 * Math.sqrt(ext[0] * ext[0] + ext[1] * ext[1] + ext[2] * ext[2]);
  if (!(radius > 0)) radius = Math.max(D.quant.step * 1e5, 1e-9);

  // A scene with a contact plane has its own ground: the generic floor would double it.
  var hasPlane = types.some(function (t) { return !!t.plane; });
  var floorHeight = Infinity;
  for (var kf = 0; kf < A.pos.length; kf += 3) {
    var hf = A.pos[kf] * D.up[0] + A.pos[kf + 1] * D.up[1] + A.pos[kf + 2] * D.up[2];
    if (hf < floorHeight) floorHeight = hf;
  }

  // ---- vectors --------------------------------------------------------------------------
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function cross(a, b) {
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  }
  function scale(a, s) { return [a[0] * s, a[1] * s, a[2] * s]; }
  function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }
  function normalize(a) {
    var n = Math.sqrt(dot(a, a));
    return n > 0 ? scale(a, 1 / n) : [0, 1, 0];
  }

  // ---- camera ---------------------------------------------------------------------------
  // Orbit camera around `target`; the world's up is against gravity. h1, h2 span the floor.
  var UP = normalize(D.up);
  // Weightless scenes get no floor: nothing falls towards it.
  var hasGravity = D.gravity;
  var h1 = Math.abs(UP[1]) > 0.7 ? [0, 0, 1] : Math.abs(UP[2]) > 0.7 ? [0, -1, 0] : [0, 0, 1];
  h1 = normalize(add(h1, scale(UP, -dot(h1, UP))));
  var h2 = cross(UP, h1);
  var FOV = 40 * Math.PI / 180;
  var cam = {};

  function defaultView() {
    var yaw = 35 * Math.PI / 180, pitch = 22 * Math.PI / 180;
    // A planar motion is shown face-on: look along its flat axis.
    var flat = -1;
    for (var c = 0; c < 3; c++) if (ext[c] <= 1e-6 * maxExt && (flat < 0 || ext[c] < ext[flat])) flat = c;
    if (maxExt > 0 && flat >= 0) {
      var axis = [0, 0, 0];
      axis[flat] = 1;
      var vertical = dot(axis, UP);
      if (Math.abs(vertical) > 0.9) {
        pitch = 80 * Math.PI / 180;
        yaw = 0;
      } else {
        if (Math.abs(vertical) > 1e-9) axis = normalize(add(axis, scale(UP, -vertical)));
        yaw = Math.atan2(dot(axis, h2), dot(axis, h1));
        pitch = 0;
      }
    }
    cam.yaw = yaw;
    cam.pitch = pitch;
    cam.dist = 1.05 * radius / Math.sin(FOV / 2);
    cam.target = centre.slice();
  }

  function viewFor(x0, y0, w, h) {
    var cp = Math.cos(cam.pitch);
    var e = add(add(scale(h1, cp * Math.cos(cam.yaw)), scale(h2, cp * Math.sin(cam.yaw))),
      scale(UP, Math.sin(cam.pitch)));
    var f = scale(e, -1);
    var r = normalize(cross(f, UP));
    var u = cross(r, f);
    return {
      eye: add(cam.target, scale(e, cam.dist)), f: f, r: r, u: u,
      focal: 0.5 * Math.min(h, w * 1.2) / Math.tan(FOV / 2),
      cx: x0 + w / 2, cy: y0 + h / 2, near: cam.dist * 1e-3, x0: x0, y0: y0, w: w, h: h
    };
  }

  function Projected() {
    this.x = new Float32Array(N);
    this.y = new Float32Array(N);
    this.z = new Float32Array(N); // camera depth; <= 0 means behind the eye
  }
  function project(v, traj, t, out) {
    var tt = Math.min(t, traj.frames - 1), base = tt * N * 3, p = traj.pos;
    var ex = v.eye[0], ey = v.eye[1], ez = v.eye[2];
    var f = v.f, r = v.r, u = v.u;
    for (var i = 0, k = base; i < N; i++, k += 3) {
      var dx = p[k] - ex, dy = p[k + 1] - ey, dz = p[k + 2] - ez;
      var z = dx * f[0] + dy * f[1] + dz * f[2];
      if (z > v.near) {
        var s = v.focal / z;
        out.x[i] = v.cx + s * (dx * r[0] + dy * r[1] + dz * r[2]);
        out.y[i] = v.cy - s * (dx * u[0] + dy * u[1] + dz * u[2]);
        out.z[i] = z;
      } else out.z[i] = -1;
    }
  }
  function projectPoint(v, p) {
    var d = [p[0] - v.eye[0], p[1] - v.eye[1], p[2] - v.eye[2]];
    var z = dot(d, v.f);
    if (z <= v.near) return null;
    var s = v.focal / z;
    return [v.cx + s * dot(d, v.r), v.cy - s * dot(d, v.u), z];
  }
  // Camera-space segment clipped at the near plane (for the floor, which passes the eye).
  function projectSegment(v, a, b) {
    var da = dot([a[0] - v.eye[0], a[1] - v.eye[1], a[2] - v.eye[2]], v.f);
    var db = dot([b[0] - v.eye[0], b[1] - v.eye[1], b[2] - v.eye[2]], v.f);
    var near = v.near * 10;
    if (da <= near && db <= near) return null;
    if (da <= near) a = add(a, scale(add(b, scale(a, -1)), (near - da) / (db - da)));
    else if (db <= near) b = add(b, scale(add(a, scale(b, -1)), (near - db) / (da - db)));
    var pa = projectPoint(v, a), pb = projectPoint(v, b);
    return pa && pb ? [pa, pb] : null;
  }

  // ---- page -----------------------------------------------------------------------------
  function el(tag, cls, text) {
    var e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }
  var canvas = el("canvas");
  canvas.id = "view";
  document.body.appendChild(canvas);
  var ctx = canvas.getContext("2d");

  var info = el("div", "panel info");
  info.appendChild(el("h1", "", D.title || "cordis"));
  var nConditional = types.filter(function (t) { return t.kind === "conditional"; }).length;
  info.appendChild(el("div", "stats", N + " particles \u00b7 " +
    (nConditional ? nConditional + " conditional types \u00b7 " : "") +
    (totalLinks || !nConditional ? totalLinks + " links \u00b7 " : "") +
    T + " frames \u00b7 dt " + fmtNumber(DT) + " s"));
  var readout = el("div", "readout");
  var frameText = el("span", "frame");
  var timeText = el("span", "time");
  readout.appendChild(frameText);
  readout.appendChild(timeText);
  info.appendChild(readout);
  var diffText = null;
  if (B) {
    diffText = el("div", "diff");
    info.appendChild(diffText);
  }
  document.body.appendChild(info);

  // Legend: link types (click to hide/show), particles, and the two motions.
  var legend = el("div", "panel legend");
  legend.appendChild(el("h2", "", "Links"));
  if (types.length === 0) legend.appendChild(el("div", "note", "none"));
  types.forEach(function (t) {
    var row = el("div", "row" + (t.drawn ? " toggle" : " off"));
    var sw = el("span", "swatch line" + (t.kind === "damper" ? " sheath" : ""));
    sw.style.background = t.colour;
    row.appendChild(sw);
    var name = el("span", "name", t.name);
    row.appendChild(name);
    row.appendChild(el("span", "kind", t.kind === "conditional"
      ? "conditional, range " + (t.range > 0 ? fmtNumber(t.range) + " m" : "?")
      : t.kind + " \u00d7 " + t.count));
    row.title = t.note || "click to hide or show";
    if (t.drawn) {
      row.addEventListener("click", function () {
        t.visible = !t.visible;
        row.classList.toggle("hidden", !t.visible);
        redraw();
      });
    } else row.appendChild(el("span", "note", t.note));
    legend.appendChild(row);
  });
  legend.appendChild(el("h2", "", "Particles"));
  // Particle rows toggle too: dense meshes read better without their dots.
  var showFree = true, showFixed = true;
  function particleRow(cls, colour, label, toggle) {
    var row = el("div", "row toggle");
    var sw = el("span", "swatch " + cls);
    sw.style.background = colour;
    row.appendChild(sw);
    row.appendChild(el("span", "name", label));
    row.title = "click to hide or show";
    row.addEventListener("click", function () {
      row.classList.toggle("hidden", !toggle());
      redraw();
    });
    legend.appendChild(row);
  }
  function toggleFree() { showFree = !showFree; return showFree; }
  function toggleFixed() { showFixed = !showFixed; return showFixed; }
  var freeColour = N > 150 && totalLinks > 0 ? FREE_COLOUR_DENSE : FREE_COLOUR;
  if (groupOf) {
    groupNames.forEach(function (g, i) {
      particleRow("dot", paletteColour(GROUP_PALETTE, i), "group " + g, toggleFree);
    });
    if (groupOf.some(function (g) { return g < 0; })) particleRow("dot", freeColour, "no group", toggleFree);
  } else particleRow("dot", freeColour, "free", toggleFree);
  if (fixed.length) particleRow("square", FIXED_COLOUR, "fixed (" + fixed.length + ")", toggleFixed);
  var showB = true;
  if (B) {
    legend.appendChild(el("h2", "", "Motions"));
    var ra = el("div", "row");
    ra.appendChild(el("span", "swatch motion-a"));
    ra.appendChild(el("span", "name", "A \u00b7 " + LABELS[0] + " (solid)"));
    legend.appendChild(ra);
    var rb = el("div", "row toggle");
    rb.appendChild(el("span", "swatch motion-b"));
    rb.appendChild(el("span", "name", "B \u00b7 " + LABELS[1] + " (dashed, pale)"));
    rb.title = "click to hide or show";
    rb.addEventListener("click", function () {
      showB = !showB;
      rb.classList.toggle("hidden", !showB);
      redraw();
    });
    legend.appendChild(rb);
  }
  document.body.appendChild(legend);

  // Controls bar.
  var bar = el("div", "panel controls");
  var playBtn = el("button", "play");
  playBtn.title = "play / pause (space)";
  bar.appendChild(playBtn);
  var slider = el("input", "slider");
  slider.type = "range";
  slider.min = 0;
  slider.max = Math.max(T - 1, 0);
  slider.step = 1;
  slider.value = 0;
  slider.title = "frame (\u2190 \u2192 step)";
  bar.appendChild(slider);
  var speedSel = el("select", "speed");
  speedSel.title = "playback speed, relative to real time";
  var SPEEDS = [0.01, 0.02, 0.05, 0.1, 0.25, 0.5, 1, 2, 4];
  SPEEDS.forEach(function (s) {
    var o = el("option", "", s + "\u00d7");
    o.value = s;
    speedSel.appendChild(o);
  });
  bar.appendChild(speedSel);
  var loopLabel = el("label", "check");
  var loopBox = el("input");
  loopBox.type = "checkbox";
  loopBox.checked = true;
  loopLabel.appendChild(loopBox);
  loopLabel.appendChild(document.createTextNode(" loop"));
  bar.appendChild(loopLabel);
  var mode = "overlay";
  var modeBtns = {};
  if (B) {
    var seg = el("div", "segmented");
    [["overlay", "Overlay"], ["side", "Side by side"]].forEach(function (m) {
      var b = el("button", "", m[1]);
      b.addEventListener("click", function () { setMode(m[0]); b.blur(); });
      modeBtns[m[0]] = b;
      seg.appendChild(b);
    });
    seg.title = "A and B overlaid or side by side (S)";
    bar.appendChild(seg);
  }
  var pngBtn = el("button", "png", "PNG");
  pngBtn.title = "save the current frame as a PNG image (P)";
  bar.appendChild(pngBtn);
  var resetBtn = el("button", "reset", "Reset view");
  resetBtn.title = "reset the camera (R, or double-click)";
  bar.appendChild(resetBtn);
  document.body.appendChild(bar);
  var help = el("div", "help", "drag: orbit \u00b7 shift-drag / right-drag: pan \u00b7 wheel: zoom \u00b7 " +
    "space: play \u00b7 \u2190 \u2192: step \u00b7 R: reset \u00b7 P: PNG");
  document.body.appendChild(help);

  // ---- state ----------------------------------------------------------------------------
  var frame = 0, fpos = 0, playing = false, lastTs = null, dirty = true;
  var duration = Math.max(T - 1, 1) * DT;
  var speed = 1;
  // Short motions play slower than real time, so that one loop lasts at least ~3 s.
  for (var si = SPEEDS.length - 1; si >= 0; si--) {
    speed = SPEEDS[si];
    if (speed <= 1 && duration / speed >= 3) break;
  }
  speedSel.value = String(speed);

  function fmtNumber(x) {
    if (x === 0) return "0";
    var a = Math.abs(x);
    if (a >= 1e4 || a < 1e-3) return x.toExponential(2);
    return String(Number(x.toPrecision(4)));
  }
  var timeDecimals = Math.min(6, Math.max(0, Math.ceil(-Math.log10(DT) - 1e-9)));
  function setFrame(f) {
    f = Math.max(0, Math.min(T - 1, f | 0));
    var changed = f !== frame;
    frame = f;
    if (changed) redraw();
    slider.value = f;
    frameText.textContent = "frame " + f + " / " + (T - 1);
    timeText.textContent = "t = " + (f * DT).toFixed(timeDecimals) + " s";
    if (B) {
      var ta = Math.min(f, A.frames - 1) * N * 3, tb = Math.min(f, B.frames - 1) * N * 3, s = 0;
      for (var k = 0; k < N * 3; k++) {
        var d = A.pos[ta + k] - B.pos[tb + k];
        s += d * d;
      }
      var txt = "RMS |A \u2212 B| = " + fmtNumber(Math.sqrt(s / N)) + " m";
      if (f >= A.frames) txt += " (A ended)";
      if (f >= B.frames) txt += " (B ended)";
      diffText.textContent = txt;
    }
  }
  function setPlaying(p) {
    playing = p && T > 1;
    if (playing && frame >= T - 1) { fpos = 0; setFrame(0); }
    fpos = frame;
    playBtn.textContent = playing ? "\u275a\u275a" : "\u25b6";
    playBtn.classList.toggle("on", playing);
    redraw();
  }
  function setMode(m) {
    mode = m;
    for (var k in modeBtns) modeBtns[k].classList.toggle("on", k === m);
    redraw();
  }
  function redraw() {
    dirty = true;
    // The state, on the page for tests (headless --dump-dom, injected scripts): frame, play
    // state, mode, speed, camera (distances in units of the motion's radius).
    document.body.setAttribute("data-frame", frame);
    document.body.setAttribute("data-state", [playing ? "playing" : "paused", mode, speed,
      cam.yaw.toFixed(4), cam.pitch.toFixed(4), (cam.dist / radius).toFixed(4),
      cam.target.map(function (c) { return (c / radius).toFixed(4); }).join(" ")].join(","));
  }

  // ---- drawing --------------------------------------------------------------------------
  var PA = new Projected(), PB = new Projected();
  // Line width and opacity by kind, relative to the springs'.
  var WIDTH = { damper: 3.2, conditional: 0.6, angle: 0.8 };
  var ALPHA = { damper: 0.32, conditional: 0.75, angle: 0.7 };
  var linkWidth = totalLinks <= 100 ? 2.2 : totalLinks <= 1000 ? 1.6 : totalLinks <= 10000 ? 1.0 : 0.7;
  var dotRadius = N <= 30 ? 4.2 : N <= 150 ? 3 : N <= 1000 ? 1.7 : N <= 5000 ? 1.3 : 1;

  function drawFloor(v) {
    // A square grid on the floor under the motion (the lowest point of A along up).
    var raw = radius / 3, p10 = Math.pow(10, Math.floor(Math.log10(raw))), m = raw / p10;
    var stepG = (m < 2 ? 1 : m < 5 ? 2 : 5) * p10;
    var n = Math.ceil(1.8 * radius / stepG);
    var hmin = floorHeight;
    var c = add(scale(UP, hmin), add(scale(h1, Math.round(dot(centre, h1) / stepG) * stepG),
      scale(h2, Math.round(dot(centre, h2) / stepG) * stepG)));
    ctx.lineWidth = 1;
    // Lines fade out away from the middle, so that the floor has no hard edge.
    for (var i = -n; i <= n; i++) {
      ctx.beginPath();
      for (var dir = 0; dir < 2; dir++) {
        var a1 = dir ? h1 : h2, a2 = dir ? h2 : h1;
        var s = projectSegment(v, add(c, add(scale(a1, i * stepG), scale(a2, -n * stepG))),
          add(c, add(scale(a1, i * stepG), scale(a2, n * stepG))));
        if (s) { ctx.moveTo(s[0][0], s[0][1]); ctx.lineTo(s[1][0], s[1][1]); }
      }
      var fade = 1 - Math.abs(i) / (n + 1);
      ctx.strokeStyle = "rgba(160,180,220," + (i === 0 ? 0.16 : 0.1 * fade).toFixed(3) + ")";
      ctx.stroke();
    }
  }

  // Each visible plane type: a translucent square of its surface (side 2.4 × the motion's
  // radius) around the motion's centre projected onto it, with a grid, in the type's colour.
  function drawPlanes(v) {
    types.forEach(function (t) {
      if (!t.plane || !t.visible) return;
      var n = normalize(t.plane.normal), p0 = t.plane.point;
      var rel = add(centre, scale(p0, -1));
      var c = add(centre, scale(n, -dot(rel, n)));
      var a1 = Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
      a1 = normalize(add(a1, scale(n, -dot(a1, n))));
      var a2 = cross(n, a1), half = 1.2 * radius, lines = 8;
      var corner = function (s1, s2) { return add(c, add(scale(a1, s1 * half), scale(a2, s2 * half))); };
      var q = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)].map(function (x) {
        return projectPoint(v, x);
      });
      ctx.save();
      ctx.strokeStyle = t.colour;
      ctx.fillStyle = t.colour;
      if (q.every(function (x) { return x; })) {
        ctx.beginPath();
        ctx.moveTo(q[0][0], q[0][1]);
        for (var k = 1; k < 4; k++) ctx.lineTo(q[k][0], q[k][1]);
        ctx.closePath();
        ctx.globalAlpha = 0.1;
        ctx.fill();
      }
      ctx.globalAlpha = 0.35;
      ctx.lineWidth = 1;
      ctx.beginPath();
      for (var i = -lines; i <= lines; i++) {
        var f = i / lines;
        for (var dir = 0; dir < 2; dir++) {
          var s = dir ? projectSegment(v, corner(f, -1), corner(f, 1))
            : projectSegment(v, corner(-1, f), corner(1, f));
          if (s) { ctx.moveTo(s[0][0], s[0][1]); ctx.lineTo(s[1][0], s[1][1]); }
        }
      }
      ctx.stroke();
      ctx.restore();
    });
  }

  // Particles below a plane (in contact): a tick from the particle up to the surface, so
  // that the penetration the buffer pushes against shows.
  function drawContacts(v, P, traj) {
    var base = Math.min(frame, traj.frames - 1) * N * 3, p = traj.pos;
    types.forEach(function (t) {
      if (!t.plane || !t.visible) return;
      var n = normalize(t.plane.normal), p0 = t.plane.point;
      ctx.beginPath();
      t.plane.members.forEach(function (i) {
        var x = [p[base + 3 * i], p[base + 3 * i + 1], p[base + 3 * i + 2]];
        var depth = dot(add(p0, scale(x, -1)), n);
        if (!(depth > 0) || !(P.z[i] > 0)) return;
        var foot = projectPoint(v, add(x, scale(n, depth)));
        if (!foot) return;
        ctx.moveTo(P.x[i], P.y[i]);
        ctx.lineTo(foot[0], foot[1]);
        ctx.moveTo(foot[0] - 5, foot[1]);
        ctx.lineTo(foot[0] + 5, foot[1]);
      });
      ctx.lineWidth = 2;
      ctx.strokeStyle = t.colour;
      ctx.stroke();
    });
  }

  var pairCache = {};
  function conditionalPairs(which, traj, t, ty, ti) {
    var key = which + ":" + ti + ":" + Math.min(t, traj.frames - 1);
    if (pairCache[key]) return pairCache[key];
    var ga = ty.groups[0], gb = ty.groups.length > 1 ? ty.groups[1] : ga;
    var r = ty.range, r2 = r * r, base = Math.min(t, traj.frames - 1) * N * 3, p = traj.pos;
    var cells = new Map(), members = [];
    for (var i = 0; i < N; i++) {
      var g = groupOf ? groupOf[i] : -1;
      if (g < 0 || (g !== ga && g !== gb)) continue;
      members.push(i);
      var key3 = Math.floor(p[base + 3 * i] / r) + "," + Math.floor(p[base + 3 * i + 1] / r) + "," +
        Math.floor(p[base + 3 * i + 2] / r);
      var list = cells.get(key3);
      if (list) list.push(i); else cells.set(key3, [i]);
    }
    var out = [];
    for (var m = 0; m < members.length && out.length < 100000; m++) {
      var a = members[m], ax = p[base + 3 * a], ay = p[base + 3 * a + 1], az = p[base + 3 * a + 2];
      var cx = Math.floor(ax / r), cy = Math.floor(ay / r), cz = Math.floor(az / r);
      for (var dx = -1; dx <= 1; dx++) for (var dy = -1; dy <= 1; dy++) for (var dz = -1; dz <= 1; dz++) {
        var l = cells.get((cx + dx) + "," + (cy + dy) + "," + (cz + dz));
        if (!l) continue;
        for (var q = 0; q < l.length; q++) {
          var b = l[q];
          if (b <= a) continue;
          var gA = groupOf[a], gB = groupOf[b];
          if (!((gA === ga && gB === gb) || (gA === gb && gB === ga))) continue;
          var ex = p[base + 3 * b] - ax, ey = p[base + 3 * b + 1] - ay, ez = p[base + 3 * b + 2] - az;
          if (ex * ex + ey * ey + ez * ez < r2) out.push(a, b);
        }
      }
    }
    if (Object.keys(pairCache).length > 64) pairCache = {};
    pairCache[key] = out;
    return out;
  }

  // Dampers often double a spring on the same pair: they are drawn first, wide and
  // translucent, as a sheath that the spring's line runs through. Then the types from the
  // last to the first, so that the top of the legend is drawn on top.
  var drawOrder = types.map(function (t, i) { return i; }).sort(function (a, b) {
    return (types[a].kind === "damper" ? 0 : 1) - (types[b].kind === "damper" ? 0 : 1) || b - a;
  });
  function drawLinks(v, P, traj, which, ghost) {
    ctx.lineCap = "round";
    ctx.lineJoin = "round";
    for (var oi = 0; oi < drawOrder.length; oi++) {
      var ti = drawOrder[oi], t = types[ti];
      if (!t.visible || !t.drawn) continue;
      var segs = t.segments;
      if (t.kind === "conditional") segs = conditionalPairs(which, traj, frame, t, ti);
      ctx.beginPath();
      if (segs) {
        for (var k = 0; k < segs.length; k += 2) {
          var a = segs[k], b = segs[k + 1];
          if (P.z[a] > 0 && P.z[b] > 0) {
            ctx.moveTo(P.x[a], P.y[a]);
            ctx.lineTo(P.x[b], P.y[b]);
          }
        }
      } else if (t.anchors) {
        for (var j = 0; j < t.anchors.length; j++) {
          var i = t.anchors[j];
          var q = projectPoint(v, [t.points[3 * j], t.points[3 * j + 1], t.points[3 * j + 2]]);
          if (!q || !(P.z[i] > 0)) continue;
          ctx.moveTo(P.x[i], P.y[i]);
          ctx.lineTo(q[0], q[1]);
          // The anchor point itself: a small cross.
          ctx.moveTo(q[0] - 4, q[1] - 4); ctx.lineTo(q[0] + 4, q[1] + 4);
          ctx.moveTo(q[0] - 4, q[1] + 4); ctx.lineTo(q[0] + 4, q[1] - 4);
        }
      }
      var w = linkWidth * (WIDTH[t.kind] || 1), alpha = ALPHA[t.kind] || 0.95;
      ctx.lineWidth = ghost ? Math.max(w, 1.2) : w;
      ctx.strokeStyle = ghost ? GHOST_COLOUR : t.colour;
      ctx.globalAlpha = ghost ? alpha * 0.5 : alpha;
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
  }

  function drawParticles(v, P, ghost) {
    var zref = cam.dist;
    function radiusOf(i) {
      var s = zref / P.z[i];
      return dotRadius * (s < 0.6 ? 0.6 : s > 1.6 ? 1.6 : s);
    }
    var ncol = !showFree ? 0 : groupOf ? groupNames.length + 1 : 1;
    for (var g = 0; g < ncol; g++) {
      var colour = !groupOf ? freeColour : g < groupNames.length ? paletteColour(GROUP_PALETTE, g) : freeColour;
      var gid = g < groupNames.length ? g : -1;
      ctx.beginPath();
      for (var i = 0; i < N; i++) {
        if (isFixed[i] || !(P.z[i] > 0)) continue;
        if (groupOf && groupOf[i] !== gid) continue;
        var r = radiusOf(i);
        if (N > 20000) { ctx.rect(P.x[i] - r, P.y[i] - r, 2 * r, 2 * r); continue; }
        ctx.moveTo(P.x[i] + r, P.y[i]);
        ctx.arc(P.x[i], P.y[i], r, 0, 2 * Math.PI);
      }
      if (ghost && N <= 300) {
        ctx.strokeStyle = GHOST_COLOUR;
        ctx.globalAlpha = 0.85;
        ctx.lineWidth = 1.2;
        ctx.setLineDash([]);
        ctx.stroke();
      } else if (ghost) {
        ctx.fillStyle = GHOST_COLOUR;
        ctx.globalAlpha = 0.4;
        ctx.fill();
      } else {
        ctx.fillStyle = colour;
        ctx.fill();
      }
      ctx.globalAlpha = 1;
    }
    // Fixed particles: squares in amber, outlined so that they read on any link colour.
    if (!showFixed) return;
    ctx.beginPath();
    for (var j = 0; j < fixed.length; j++) {
      var f = fixed[j];
      if (!(P.z[f] > 0)) continue;
      var s = radiusOf(f) * 1.35 + 1;
      ctx.rect(P.x[f] - s, P.y[f] - s, 2 * s, 2 * s);
    }
    if (ghost) {
      ctx.strokeStyle = GHOST_COLOUR;
      ctx.lineWidth = 1.2;
      ctx.stroke();
    } else {
      ctx.fillStyle = FIXED_COLOUR;
      ctx.fill();
      ctx.strokeStyle = "rgba(10,14,22,0.9)";
      ctx.lineWidth = 1.2;
      ctx.stroke();
    }
  }

  function drawAxes(x, y) {
    // Orientation gizmo: world x, y, z as seen by the camera (no perspective).
    var v = viewFor(0, 0, 1, 1), L = 20;
    var axes = [[[1, 0, 0], "x", "#ff6b6b"], [[0, 1, 0], "y", "#69db7c"], [[0, 0, 1], "z", "#74c0fc"]];
    axes.sort(function (a, b) { return dot(b[0], v.f) - dot(a[0], v.f); });
    ctx.font = "11px system-ui, sans-serif";
    ctx.textAlign = "center";
    ctx.textBaseline = "middle";
    axes.forEach(function (a) {
      var dx = dot(a[0], v.r) * L, dy = -dot(a[0], v.u) * L;
      ctx.beginPath();
      ctx.moveTo(x, y);
      ctx.lineTo(x + dx, y + dy);
      ctx.strokeStyle = a[2];
      ctx.lineWidth = 2;
      ctx.stroke();
      ctx.fillStyle = a[2];
      // An axis pointing at the eye has no length: its label would sit on the origin.
      if (dx * dx + dy * dy > 16) ctx.fillText(a[1], x + dx * 1.4, y + dy * 1.4);
    });
  }

  function drawViewport(x0, y0, w, h, showA, showBHere, label) {
    var v = viewFor(x0, y0, w, h);
    ctx.save();
    ctx.beginPath();
    ctx.rect(x0, y0, w, h);
    ctx.clip();
    if (hasGravity && !hasPlane) drawFloor(v);
    if (hasPlane) drawPlanes(v);
    if (showBHere) {
      // Overlaid, B is dashed and pale under A; alone in its half, it is drawn like A.
      project(v, B, frame, PB);
      if (showA) ctx.setLineDash([6, 4]);
      drawLinks(v, PB, B, "b", showA);
      ctx.setLineDash([]);
      drawParticles(v, PB, showA);
    }
    if (showA) {
      project(v, A, frame, PA);
      drawLinks(v, PA, A, "a", false);
      if (hasPlane) drawContacts(v, PA, A);
      drawParticles(v, PA, false);
    }
    if (label) {
      ctx.font = "600 13px system-ui, sans-serif";
      ctx.textAlign = "center";
      ctx.textBaseline = "bottom";
      ctx.fillStyle = "rgba(230,235,245,0.85)";
      ctx.fillText(label, x0 + w / 2, y0 + h - 22);
    }
    ctx.restore();
  }

  var cssW = 0, cssH = 0;
  function resize() {
    var dpr = window.devicePixelRatio || 1;
    cssW = window.innerWidth;
    cssH = window.innerHeight;
    canvas.width = Math.round(cssW * dpr);
    canvas.height = Math.round(cssH * dpr);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    dirty = true;
  }

  function draw() {
    var started = performance.now();
    ctx.clearRect(0, 0, cssW, cssH);
    // The bar at the bottom covers part of the page: centre the scene above it.
    var hUse = cssH - 64;
    // The legend sits at the top right: the scene is drawn left of it, so that it never
    // covers a panel (unless the window is too narrow to spare its width).
    var reserve = legend.offsetWidth + 28;
    var wUse = reserve <= 0.4 * cssW ? cssW - reserve : cssW;
    // The info panel sits at the top left: the scene starts below it, in both modes, so that
    // it never covers the motion (unless the window is too short to spare its height).
    var top = info.offsetTop + info.offsetHeight + 8;
    if (top > 0.35 * hUse) top = 0;
    if (B && mode === "side") {
      var half = wUse / 2;
      drawViewport(0, top, half, hUse - top, true, false, "A \u00b7 " + LABELS[0]);
      drawViewport(half, top, wUse - half, hUse - top, false, showB, "B \u00b7 " + LABELS[1]);
      ctx.beginPath();
      ctx.moveTo(half + 0.5, top);
      ctx.lineTo(half + 0.5, hUse - 20);
      ctx.strokeStyle = "rgba(255,255,255,0.12)";
      ctx.lineWidth = 1;
      ctx.stroke();
    } else {
      drawViewport(0, top, wUse, hUse - top, true, !!B && showB, null);
    }
    drawAxes(40, cssH - 110);
    dirty = false;
    // For tests: the right edge of the scene's drawing area (px), left of the legend, and its
    // top, below the info panel.
    document.body.setAttribute("data-scene-right", wUse.toFixed(0));
    document.body.setAttribute("data-scene-top", top.toFixed(0));
    // For tests (headless --dump-dom) and the curious: how fast the last frame was built.
    document.body.setAttribute("data-draw-ms", (performance.now() - started).toFixed(2));
  }

  // The current frame as a PNG file: the drawing at the screen's resolution (the scene, the
  // panel labels and the axes; not the HTML panels) on the page's darkest background colour,
  // named after the page's title and the frame. A data: URL, so nothing leaves the page.
  function savePng() {
    draw();
    var out = document.createElement("canvas");
    out.width = canvas.width;
    out.height = canvas.height;
    var g = out.getContext("2d");
    g.fillStyle = "#090c14";
    g.fillRect(0, 0, out.width, out.height);
    g.drawImage(canvas, 0, 0);
    var a = document.createElement("a");
    var name = String(D.title || "cordis").replace(/[^A-Za-z0-9._-]+/g, "_").slice(0, 60);
    a.download = name + "-frame" + frame + ".png";
    a.href = out.toDataURL("image/png");
    document.body.appendChild(a);
    a.click();
    a.remove();
    return a;
  }
  pngBtn.addEventListener("click", function () { savePng(); pngBtn.blur(); });

  // ---- interaction ----------------------------------------------------------------------
  var pointers = new Map(), dragMode = null, pinchDist = 0;
  canvas.addEventListener("contextmenu", function (e) { e.preventDefault(); });
  canvas.addEventListener("pointerdown", function (e) {
    try { canvas.setPointerCapture(e.pointerId); } catch (err) { /* pointer already gone */ }
    pointers.set(e.pointerId, [e.clientX, e.clientY]);
    dragMode = e.button === 2 || e.button === 1 || e.shiftKey ? "pan" : "orbit";
    if (pointers.size === 2) {
      var p = Array.from(pointers.values());
      pinchDist = Math.hypot(p[0][0] - p[1][0], p[0][1] - p[1][1]);
    }
    canvas.classList.add("dragging");
  });
  canvas.addEventListener("pointermove", function (e) {
    var prev = pointers.get(e.pointerId);
    if (!prev) return;
    var dx = e.clientX - prev[0], dy = e.clientY - prev[1];
    pointers.set(e.pointerId, [e.clientX, e.clientY]);
    if (pointers.size === 2) {
      var p = Array.from(pointers.values());
      var d = Math.hypot(p[0][0] - p[1][0], p[0][1] - p[1][1]);
      if (pinchDist > 0 && d > 0) zoom(pinchDist / d);
      pinchDist = d;
      return;
    }
    if (dragMode === "pan") {
      var v = viewFor(0, 0, cssW, cssH - 64);
      var perPixel = cam.dist / v.focal;
      cam.target = add(cam.target, add(scale(v.r, -dx * perPixel), scale(v.u, dy * perPixel)));
    } else {
      cam.yaw -= dx * 0.008;
      cam.pitch = Math.max(-1.55, Math.min(1.55, cam.pitch + dy * 0.008));
    }
    redraw();
  });
  function endDrag(e) {
    pointers.delete(e.pointerId);
    if (pointers.size === 0) canvas.classList.remove("dragging");
  }
  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  function zoom(factor) {
    cam.dist = Math.max(radius * 1e-3, Math.min(radius * 1e4, cam.dist * factor));
    redraw();
  }
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    var unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1;
    zoom(Math.exp(Math.max(-1, Math.min(1, e.deltaY * unit * 0.0015))));
  }, { passive: false });
  canvas.addEventListener("dblclick", function () { defaultView(); redraw(); });

  playBtn.addEventListener("click", function () { setPlaying(!playing); playBtn.blur(); });
  slider.addEventListener("input", function () { setFrame(+slider.value); fpos = frame; });
  speedSel.addEventListener("change", function () { speed = +speedSel.value; speedSel.blur(); redraw(); });
  resetBtn.addEventListener("click", function () { defaultView(); redraw(); resetBtn.blur(); });
  window.addEventListener("keydown", function (e) {
    if (e.target && e.target.tagName === "SELECT") return;
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    var key = e.key;
    if (key === " " || key === "k") setPlaying(!playing);
    else if (key === "ArrowRight" || key === "ArrowLeft") {
      setPlaying(false);
      setFrame(frame + (key === "ArrowRight" ? 1 : -1) * (e.shiftKey ? 10 : 1));
    } else if (key === "Home") setFrame(0);
    else if (key === "End") setFrame(T - 1);
    else if (key === "r" || key === "R") { defaultView(); redraw(); }
    else if (key === "p" || key === "P") savePng();
    else if ((key === "s" || key === "S") && B) setMode(mode === "side" ? "overlay" : "side");
    else return;
    e.preventDefault();
  });
  window.addEventListener("resize", resize);

  function tick(ts) {
    if (playing) {
      var elapsed = lastTs === null ? 0 : Math.min(0.25, (ts - lastTs) / 1000);
      fpos += elapsed * speed / DT;
      if (fpos > T - 1) {
        if (loopBox.checked) fpos = 0;
        else { fpos = T - 1; setPlaying(false); }
      }
      setFrame(Math.floor(fpos));
    }
    lastTs = ts;
    if (dirty) draw();
    requestAnimationFrame(tick);
  }

  // ---- start ----------------------------------------------------------------------------
  // The address may fix the state, for screenshots and links: #frame=40&mode=side&view=yaw,pitch,zoom
  // (degrees; zoom > 1 brings the camera closer). A fixed frame starts paused.
  var hash = {};
  location.hash.replace(/^#/, "").split("&").forEach(function (kv) {
    var i = kv.indexOf("=");
    if (i > 0) hash[decodeURIComponent(kv.slice(0, i))] = decodeURIComponent(kv.slice(i + 1));
  });
  defaultView();
  if (hash.view) {
    var vv = hash.view.split(",").map(Number);
    if (isFinite(vv[0])) cam.yaw = vv[0] * Math.PI / 180;
    if (isFinite(vv[1])) cam.pitch = Math.max(-89, Math.min(89, vv[1])) * Math.PI / 180;
    if (vv[2] > 0) cam.dist /= vv[2];
  }
  resize();
  frame = -1;
  setFrame(hash.frame !== undefined && isFinite(+hash.frame) ? +hash.frame : 0);
  setMode(B && hash.mode === "side" ? "side" : "overlay");
  setPlaying(hash.frame === undefined);
  draw();
  if (+hash.bench > 0) {
    // #bench=K: draw K times and record the mean time, for timing tests.
    var t0 = performance.now();
    for (var b = 0; b < +hash.bench; b++) draw();
    document.body.setAttribute("data-draw-ms", ((performance.now() - t0) / +hash.bench).toFixed(2));
  }
  requestAnimationFrame(tick);
})();
