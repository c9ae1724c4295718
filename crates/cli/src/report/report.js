// The report's animation: the whisker and the object on one canvas, a time series with a
// cursor on another, and the particle filter's cloud on a third, all following one frame index.
// Plain script, no libraries. `window.vibrissaReport` lets a test (or a console) drive it.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("vibrissa-data").textContent);
  var FPS = 25;
  var CAPTION = 24;
  var byId = function (id) { return document.getElementById(id); };
  var runSelect = byId("run"), playButton = byId("play"), scrub = byId("scrub");
  var clock = byId("clock"), channel = byId("channel"), estimates = byId("estimates");
  var whisker = byId("whisker"), series = byId("series"), cloud = byId("cloud");
  var state = { index: 0, frame: 0, timer: null, drawnTip: null, restTip: null, view: null };

  if (!data.runs.length) {
    byId("animation").hidden = true;
    return;
  }

  data.runs.forEach(function (r, i) {
    var o = document.createElement("option");
    o.value = String(i);
    o.textContent = "run " + r.index + ": " + r.label + (r.template ? " (template)" : "");
    runSelect.appendChild(o);
  });

  function current() { return data.runs[state.index]; }

  // Node k of run r at frame f, m.
  function node(r, f, k) { return [r.nodes[f][2 * k] / 1e6, r.nodes[f][2 * k + 1] / 1e6]; }
  function nodeCount(r) { return r.nodes[0].length / 2; }

  // The world shown: every shape the whisker takes with a margin of a fifth of its size,
  // widened to the canvas' aspect (as the GIFs of `vibrissa simulate --animate`).
  function viewOf(r, aspect) {
    var b = [Infinity, -Infinity, Infinity, -Infinity];
    r.nodes.forEach(function (n) {
      for (var i = 0; i < n.length; i += 2) {
        var x = n[i] / 1e6, y = n[i + 1] / 1e6;
        b = [Math.min(b[0], x), Math.max(b[1], x), Math.min(b[2], y), Math.max(b[3], y)];
      }
    });
    var size = Math.max(b[1] - b[0], b[3] - b[2], 1e-6), m = 0.2 * size;
    var x0 = b[0] - m, x1 = b[1] + m, y0 = b[2] - m, y1 = b[3] + m;
    var w = x1 - x0, h = y1 - y0;
    if (w < aspect * h) { var gx = 0.5 * (aspect * h - w); x0 -= gx; x1 += gx; }
    else { var gy = 0.5 * (w / aspect - h); y0 -= gy; y1 += gy; }
    return [x0, x1, y0, y1];
  }

  function toPixel(v, p) {
    var sx = whisker.width / (v[1] - v[0]);
    var sy = (whisker.height - CAPTION) / (v[3] - v[2]);
    return [(p[0] - v[0]) * sx, CAPTION + (v[3] - p[1]) * sy];
  }

  // An object's outline at frame f, world m.
  function outline(shape, pose, reach) {
    var x = pose[0] / 1e6, y = pose[1] / 1e6, a = pose[2] / 1e6;
    var c = Math.cos(a), s = Math.sin(a), local = [];
    if (shape.shape === "polygon") {
      local = shape.vertices.map(function (p) { return [p[0] / 1e6, p[1] / 1e6]; });
    } else if (shape.shape === "circle") {
      for (var k = 0; k < 32; k++) {
        var t = 2 * Math.PI * k / 32, rad = shape.radius / 1e6;
        local.push([rad * Math.cos(t), rad * Math.sin(t)]);
      }
    } else {
      local = [[-reach, 0], [reach, 0], [reach, -reach], [-reach, -reach]];
    }
    return local.map(function (p) { return [x + c * p[0] - s * p[1], y + s * p[0] + c * p[1]]; });
  }

  function polyline(ctx, points) {
    ctx.beginPath();
    points.forEach(function (p, i) { if (i) { ctx.lineTo(p[0], p[1]); } else { ctx.moveTo(p[0], p[1]); } });
  }

  function touching(r, f) { return r.contact[r.frames[f]] === 1; }
  function time(r, f) { return r.t[r.frames[f]]; }

  function drawWhisker() {
    var r = current(), f = state.frame, v = state.view, ctx = whisker.getContext("2d");
    var hit = touching(r, f);
    ctx.clearRect(0, 0, whisker.width, whisker.height);
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, whisker.width, whisker.height);
    var reach = 4 * Math.max(v[1] - v[0], v[3] - v[2]);
    r.objects.forEach(function (shape, o) {
      var pts = outline(shape, r.poses[f][o], reach).map(function (p) { return toPixel(v, p); });
      polyline(ctx, pts);
      ctx.closePath();
      ctx.fillStyle = hit ? "#f0aaaa" : "#aac8e6";
      ctx.fill();
      ctx.lineWidth = 2;
      ctx.strokeStyle = hit ? "#c82828" : "#1f77b4";
      ctx.stroke();
    });
    var n = nodeCount(r), rest = [], now = [];
    for (var k = 0; k < n; k++) {
      rest.push(toPixel(v, node(r, 0, k)));
      now.push(toPixel(v, node(r, f, k)));
    }
    polyline(ctx, rest);
    ctx.lineWidth = 2;
    ctx.strokeStyle = "#c0c0c0";
    ctx.stroke();
    polyline(ctx, now);
    ctx.lineWidth = 3;
    ctx.strokeStyle = "#000";
    ctx.lineJoin = "round";
    ctx.stroke();
    ctx.beginPath();
    ctx.arc(now[0][0], now[0][1], 5, 0, 2 * Math.PI);
    ctx.fillStyle = "#000";
    ctx.fill();
    state.drawnTip = now[n - 1];
    state.restTip = rest[n - 1];
    // Caption.
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, whisker.width, CAPTION);
    ctx.font = "14px sans-serif";
    ctx.fillStyle = "#444";
    ctx.fillText("run " + r.index + ": " + r.label, 8, 17);
    ctx.fillStyle = hit ? "#c82828" : "#444";
    ctx.fillText("t = " + time(r, f).toFixed(1) + " ms" + (hit ? "  contact" : ""), whisker.width - 170, 17);
  }

  function finite(xs) { return xs.filter(function (x) { return x !== null && isFinite(x); }); }

  function drawSeries() {
    var r = current(), ctx = series.getContext("2d"), name = channel.value;
    var ys = r[name], ts = r.t, W = series.width, H = series.height;
    var left = 70, right = 12, top = 12, bottom = 26;
    ctx.clearRect(0, 0, W, H);
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, W, H);
    var ok = finite(ys);
    var lo = Math.min.apply(null, ok), hi = Math.max.apply(null, ok);
    if (!(hi > lo)) { lo -= 1; hi += 1; }
    var pad = 0.05 * (hi - lo);
    lo -= pad; hi += pad;
    var t0 = ts[0], t1 = ts[ts.length - 1] || 1;
    var px = function (t) { return left + (t - t0) / (t1 - t0 || 1) * (W - left - right); };
    var py = function (y) { return top + (hi - y) / (hi - lo) * (H - top - bottom); };
    // Contact shading.
    ctx.fillStyle = "#ffe0b0";
    var dt = ts.length > 1 ? ts[1] - ts[0] : 1;
    r.contact.forEach(function (c, k) {
      if (c === 1) { ctx.fillRect(px(ts[k] - dt / 2), top, px(ts[k] + dt / 2) - px(ts[k] - dt / 2), H - top - bottom); }
    });
    // Axes and labels.
    ctx.strokeStyle = "#999";
    ctx.lineWidth = 1;
    ctx.strokeRect(left, top, W - left - right, H - top - bottom);
    ctx.fillStyle = "#444";
    ctx.font = "12px sans-serif";
    ctx.fillText(hi.toPrecision(3), 4, top + 10);
    ctx.fillText(lo.toPrecision(3), 4, H - bottom);
    ctx.fillText(t0.toFixed(0) + " ms", left, H - 8);
    ctx.fillText(t1.toFixed(0) + " ms", W - right - 50, H - 8);
    ctx.fillText(channel.options[channel.selectedIndex].text, left + 8, top + 14);
    // The series.
    ctx.beginPath();
    var pen = false;
    ys.forEach(function (y, k) {
      if (y === null || !isFinite(y)) { pen = false; return; }
      if (pen) { ctx.lineTo(px(ts[k]), py(y)); } else { ctx.moveTo(px(ts[k]), py(y)); pen = true; }
    });
    ctx.strokeStyle = "#1f77b4";
    ctx.lineWidth = 1.5;
    ctx.stroke();
    // The cursor.
    var x = px(time(r, state.frame));
    ctx.beginPath();
    ctx.moveTo(x, top);
    ctx.lineTo(x, H - bottom);
    ctx.strokeStyle = "#c82828";
    ctx.lineWidth = 2;
    ctx.stroke();
  }

  function drawCloud() {
    var r = current(), ctx = cloud.getContext("2d"), W = cloud.width, H = cloud.height;
    ctx.clearRect(0, 0, W, H);
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, W, H);
    ctx.font = "12px sans-serif";
    ctx.fillStyle = "#444";
    if (!r.pf) {
      ctx.fillText("No particle filter in this experiment", 12, 24);
      ctx.fillText("(run it with --particles N).", 12, 42);
      return;
    }
    var pf = r.pf, two = pf.unknowns.length > 1;
    var left = 44, right = 10, top = 22, bottom = 30;
    var range = function (u) {
      var k = data.unknowns.indexOf(pf.unknowns[u]);
      var a = k >= 0 ? data.ranges[k] : [0, 1], w = a[1] - a[0];
      return [a[0] - 0.15 * w, a[1] + 0.15 * w];
    };
    var rx = range(0), ry = two ? range(1) : [0, 1];
    var px = function (x) { return left + (x - rx[0]) / (rx[1] - rx[0]) * (W - left - right); };
    var py = function (y) { return top + (ry[1] - y) / (ry[1] - ry[0]) * (H - top - bottom); };
    ctx.strokeStyle = "#999";
    ctx.strokeRect(left, top, W - left - right, H - top - bottom);
    var unit = function (u) { return u === "d" ? [1e3, "mm"] : u === "v" ? [1, "m/s"] : [1, ""]; };
    var ux = unit(pf.unknowns[0]);
    ctx.fillText("particle cloud (" + pf.particles + " particles, " + (pf.points[0].length / pf.unknowns.length) + " drawn)", 8, 14);
    ctx.fillText(pf.unknowns[0] + " (" + ux[1] + ")  " + (rx[0] * ux[0]).toFixed(1) + " … " + (rx[1] * ux[0]).toFixed(1), left, H - 10);
    if (two) {
      var uy = unit(pf.unknowns[1]);
      ctx.save();
      ctx.translate(14, H - bottom);
      ctx.rotate(-Math.PI / 2);
      ctx.fillText(pf.unknowns[1] + " (" + uy[1] + ")  " + (ry[0] * uy[0]).toFixed(2) + " … " + (ry[1] * uy[0]).toFixed(2), 0, 0);
      ctx.restore();
    }
    var pts = pf.points[state.frame], m = pf.unknowns.length, count = pts.length / m;
    ctx.fillStyle = "rgba(31, 119, 180, 0.45)";
    for (var i = 0; i < count; i++) {
      var x = pts[i * m] / pf.scale[0];
      var y = two ? pts[i * m + 1] / pf.scale[1] : (i + 0.5) / count;
      ctx.beginPath();
      ctx.arc(px(x), py(y), 2.5, 0, 2 * Math.PI);
      ctx.fill();
    }
    // The truth (a red cross) and the posterior mean (a black ring).
    var tx = px(r.truth[0]), ty = two ? py(r.truth[1]) : py(0.5);
    ctx.strokeStyle = "#c82828";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(tx - 6, ty - 6); ctx.lineTo(tx + 6, ty + 6);
    ctx.moveTo(tx - 6, ty + 6); ctx.lineTo(tx + 6, ty - 6);
    ctx.stroke();
    var mean = pf.mean[state.frame];
    ctx.strokeStyle = "#000";
    ctx.beginPath();
    ctx.arc(px(mean[0]), two ? py(mean[1]) : py(0.5), 5, 0, 2 * Math.PI);
    ctx.stroke();
  }

  function describe(values) {
    return values.map(function (x, u) {
      var name = data.unknowns[u];
      return name === "d" ? "d = " + (x * 1e3).toFixed(2) + " mm" : name + " = " + x.toFixed(3) + (name === "v" ? " m/s" : "");
    }).join(", ");
  }

  function showEstimates() {
    var r = current(), parts = ["truth: " + describe(r.truth)];
    r.estimates.forEach(function (e) { parts.push(e[0] + ": " + describe(e[1])); });
    if (!r.estimates.length) { parts.push("a template (not evaluated)"); }
    if (r.pf) { parts.push("particle filter re-run here: " + describe(r.pf.last.slice(0, data.unknowns.length))); }
    estimates.textContent = parts.join(" · ");
  }

  function draw() {
    var r = current();
    clock.textContent = "frame " + (state.frame + 1) + " / " + r.frames.length + ", t = " + time(r, state.frame).toFixed(1) + " ms";
    whisker.dataset.frame = String(state.frame);
    drawWhisker();
    drawSeries();
    drawCloud();
  }

  function seek(f) {
    var n = current().frames.length;
    state.frame = Math.max(0, Math.min(n - 1, Math.round(f)));
    scrub.value = String(state.frame);
    draw();
  }

  function pause() {
    if (state.timer !== null) { clearInterval(state.timer); state.timer = null; }
    playButton.textContent = "Play";
  }

  function play() {
    if (state.timer !== null) { return; }
    playButton.textContent = "Pause";
    state.timer = setInterval(function () {
      var n = current().frames.length;
      seek(state.frame + 1 >= n ? 0 : state.frame + 1);
    }, 1000 / FPS);
  }

  function select(i) {
    state.index = Math.max(0, Math.min(data.runs.length - 1, i));
    runSelect.value = String(state.index);
    var r = current();
    state.view = viewOf(r, whisker.width / (whisker.height - CAPTION));
    scrub.max = String(r.frames.length - 1);
    showEstimates();
    seek(0);
  }

  runSelect.addEventListener("change", function () { select(Number(runSelect.value)); });
  playButton.addEventListener("click", function () { if (state.timer === null) { play(); } else { pause(); } });
  scrub.addEventListener("input", function () { pause(); seek(Number(scrub.value)); });
  channel.addEventListener("change", draw);

  window.vibrissaReport = {
    runs: function () { return data.runs.map(function (r) { return r.index; }); },
    select: select,
    run: function () { return current().index; },
    frames: function () { return current().frames.length; },
    frame: function () { return state.frame; },
    seek: seek,
    play: play,
    pause: pause,
    playing: function () { return state.timer !== null; },
    // Frames at which the whisker touches the object.
    contactFrames: function () {
      var r = current(), out = [];
      r.frames.forEach(function (s, f) { if (r.contact[s] === 1) { out.push(f); } });
      return out;
    },
    // Canvas pixels of the whisker's tip as last drawn, and of the tip at rest.
    drawnTip: function () { return state.drawnTip.slice(); },
    restTip: function () { return state.restTip.slice(); },
    hasCloud: function () { return !!current().pf; }
  };
  select(0);
})();
