// mitlc report: draws the charts and animates the net's marking along a run's greedy rollout.
// The markings are the runtime's (mitlc.cli.reports.training.rollout_markings), read from the
// page's data; nothing here steps the net. #run=R&step=K in the address chooses a run and step.
(function () {
  "use strict";
  var SVG = "http://www.w3.org/2000/svg";
  var node = document.getElementById("report-data");
  if (!node) { return; }
  var data = JSON.parse(node.textContent);

  function el(tag, attrs, parent, text) {
    var e = document.createElementNS(SVG, tag);
    for (var k in attrs) { if (Object.prototype.hasOwnProperty.call(attrs, k)) { e.setAttribute(k, attrs[k]); } }
    if (text !== undefined) { e.textContent = text; }
    if (parent) { parent.appendChild(e); }
    return e;
  }

  function fmt(v) {
    if (v === null || v === undefined) { return "–"; }
    var a = Math.abs(v);
    if (a !== 0 && (a >= 1e4 || a < 1e-2)) { return v.toExponential(1); }
    return (Math.round(v * 100) / 100).toString();
  }

  function extent(lists, extra) {
    var lo = Infinity, hi = -Infinity;
    lists.forEach(function (ys) { ys.forEach(function (y) { if (y !== null) { lo = Math.min(lo, y); hi = Math.max(hi, y); } }); });
    (extra || []).forEach(function (y) { if (y !== null && isFinite(y)) { lo = Math.min(lo, y); hi = Math.max(hi, y); } });
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi - lo < 1e-12) { lo -= 1; hi += 1; }
    var pad = (hi - lo) * 0.06;
    return [lo - pad, hi + pad];
  }

  // A line chart: opts.x (numbers), opts.series [{y, cls}], opts.title, opts.xlabel, opts.lines (dashed
  // horizontal lines), opts.cursor (draw a cursor line, returned). Nulls break the line.
  function lineChart(parent, opts) {
    var W = opts.width || 560, H = opts.height || 150, L = 52, R = 10, T = 20, B = 26;
    var svg = el("svg", { "class": "chart", viewBox: "0 0 " + W + " " + H, role: "img" }, parent);
    var xs = opts.x, x0 = xs[0], x1 = xs[xs.length - 1];
    if (x1 === x0) { x1 = x0 + 1; }
    var yr = extent(opts.series.map(function (s) { return s.y; }), opts.lines || []);
    function px(x) { return L + (x - x0) / (x1 - x0) * (W - L - R); }
    function py(y) { return T + (1 - (y - yr[0]) / (yr[1] - yr[0])) * (H - T - B); }
    for (var i = 0; i <= 4; i++) {
      var yv = yr[0] + (yr[1] - yr[0]) * i / 4;
      el("line", { "class": "grid", x1: L, x2: W - R, y1: py(yv), y2: py(yv) }, svg);
      el("text", { x: L - 4, y: py(yv) + 4, "text-anchor": "end" }, svg, fmt(yv));
    }
    for (var j = 0; j <= 5; j++) {
      var xv = x0 + (x1 - x0) * j / 5;
      el("text", { x: px(xv), y: H - 10, "text-anchor": "middle" }, svg, fmt(xv));
    }
    el("line", { "class": "axis", x1: L, x2: L, y1: T, y2: H - B }, svg);
    el("line", { "class": "axis", x1: L, x2: W - R, y1: H - B, y2: H - B }, svg);
    el("text", { "class": "title", x: L, y: 13 }, svg, opts.title || "");
    if (opts.xlabel) { el("text", { x: W - R, y: 13, "text-anchor": "end" }, svg, opts.xlabel); }
    (opts.lines || []).forEach(function (y) {
      if (y !== null && isFinite(y)) { el("line", { "class": "box", x1: L, x2: W - R, y1: py(y), y2: py(y) }, svg); }
    });
    opts.series.forEach(function (s) {
      var d = "", pen = false;
      s.y.forEach(function (y, k) {
        if (y === null) { pen = false; return; }
        d += (pen ? "L" : "M") + px(xs[k]).toFixed(1) + "," + py(y).toFixed(1);
        pen = true;
      });
      el("path", { "class": s.cls, d: d }, svg);
    });
    if (opts.marker !== undefined && opts.marker !== null) {
      el("line", { "class": "violation", x1: px(opts.marker), x2: px(opts.marker), y1: T, y2: H - B }, svg);
    }
    var cursor = null;
    if (opts.cursor) { cursor = el("line", { "class": "cursor", x1: L, x2: L, y1: T, y2: H - B }, svg); }
    return { svg: svg, px: px, cursor: cursor };
  }

  // The propositions' truth over time: one band per proposition, filled where it holds.
  function bands(parent, ro, run) {
    var W = 560, L = 52, R = 10, T = 20, row = 18, names = Object.keys(run.truth);
    var H = T + row * names.length + 26;
    var svg = el("svg", { "class": "chart", viewBox: "0 0 " + W + " " + H, role: "img" }, parent);
    var n = ro.steps + 1, w = (W - L - R) / n;
    el("text", { "class": "title", x: L, y: 13 }, svg, "propositions (filled: true)");
    names.forEach(function (a, i) {
      var y = T + i * row, bits = run.truth[a];
      el("rect", { "class": "band-false", x: L, y: y + 2, width: W - L - R, height: row - 4 }, svg);
      var k = 0;
      while (k < n) {
        if (bits[k] === "1") {
          var s = k;
          while (k < n && bits[k] === "1") { k++; }
          el("rect", { "class": "band-true", x: L + s * w, y: y + 2, width: (k - s) * w, height: row - 4 }, svg);
        } else { k++; }
      }
      el("text", { x: L - 4, y: y + row - 5, "text-anchor": "end" }, svg, a);
    });
    for (var j = 0; j <= 5; j++) {
      var t = ro.steps * ro.dt * j / 5;
      el("text", { x: L + (W - L - R) * j / 5, y: H - 8, "text-anchor": "middle" }, svg, fmt(t));
    }
    el("text", { x: W - R, y: 13, "text-anchor": "end" }, svg, "t (s)");
    var cursor = el("line", { "class": "cursor", x1: L, x2: L, y1: T, y2: T + row * names.length }, svg);
    return { svg: svg, px: function (t) { return L + (t / ro.dt + 0.5) * w; }, cursor: cursor };
  }

  // ---------------------------------------------------------------- learning curves
  var lc = document.getElementById("curves");
  if (lc && data.curves && data.curves.x.length) {
    var series = data.curves.runs.map(function (y) { return { y: y, cls: "run" }; });
    series.push({ y: data.curves.mean, cls: "mean" });
    lineChart(lc, {
      x: data.curves.x, series: series, width: 900, height: 280,
      title: "return per trial: every run (grey) and their mean (blue)" +
        (data.curves.binned > 1 ? ", means of " + data.curves.binned + " trials" : ""),
      xlabel: "trial"
    });
  }

  // ---------------------------------------------------------------- the rollout
  var ro = data.rollout;
  if (ro) {
    var slider = document.getElementById("step");
    var label = document.getElementById("step-label");
    var choose = document.getElementById("run");
    var play = document.getElementById("play");
    var traj = document.getElementById("trajectory");
    var places = [];
    var netSvg = document.querySelector("#net svg");
    if (netSvg) {
      netSvg.querySelectorAll("g.node").forEach(function (g) {
        var title = g.querySelector("title");
        var m = title && /^P(\d+)$/.exec(title.textContent.trim());
        if (!m) { return; }
        var i = +m[1], ell = g.querySelector("ellipse");
        g.classList.add("place");
        g.setAttribute("data-place", ro.places[i]);
        var tok = null;
        g.querySelectorAll("text").forEach(function (t) {  // Graphviz's token label sits at the circle's centre
          if (!tok && ell && t.getAttribute("x") === ell.getAttribute("cx")) { tok = t; }
        });
        if (tok) { tok.textContent = ""; tok.setAttribute("class", "tok"); }
        else if (ell) { tok = el("text", { "class": "tok", x: ell.getAttribute("cx"), y: +ell.getAttribute("cy") + 4, "text-anchor": "middle" }, g); }
        places[i] = { g: g, tok: tok };
      });
    }
    var charts = [], state = { run: 0, step: 0, timer: null };

    function drawRun(r) {
      var run = ro.runs[r], t = [];
      for (var k = 0; k <= ro.steps; k++) { t.push(k * ro.dt); }
      while (traj.firstChild) { traj.removeChild(traj.firstChild); }
      charts = [];
      var v = data.verdicts[r], at = v && v.violation_time !== null ? v.violation_time : null;
      ro.state_names.forEach(function (name, j) {
        charts.push(lineChart(traj, { x: t, series: [{ y: run.states[j], cls: "series s" + j }], title: name,
          xlabel: "t (s)", cursor: true, marker: at }));
      });
      var tu = t.slice(0, ro.steps);
      ro.input_names.forEach(function (name, j) {
        var box = ro.input_box[j] || [null, null];
        charts.push(lineChart(traj, { x: tu, series: [{ y: run.inputs[j], cls: "series input" }],
          title: "input " + name, xlabel: "t (s)", lines: box, cursor: true }));
      });
      charts.push(bands(traj, ro, run));
      document.querySelectorAll("tr.run-row").forEach(function (tr) {
        tr.classList.toggle("chosen", +tr.getAttribute("data-run") === r);
      });
      var verdict = document.getElementById("run-verdict");
      if (verdict && v) {
        verdict.textContent = v.verdict ? "satisfied, robustness " + fmt(v.robustness)
          : "violated at t = " + fmt(v.violation_time) + " s by " + v.failing + ", robustness " + fmt(v.robustness);
        verdict.className = v.verdict ? "ok" : "bad";
      }
    }

    function setStep(k) {
      k = Math.max(0, Math.min(ro.steps, k | 0));
      state.step = k;
      var marked = {};
      ro.runs[state.run].marks[k].forEach(function (m) {
        if (Array.isArray(m)) { marked[m[0]] = m[1]; } else { marked[m] = 1; }
      });
      places.forEach(function (p, i) {
        if (!p) { return; }
        var n = marked[i] || 0;
        p.g.setAttribute("data-tokens", String(n));
        p.g.classList.toggle("marked", n > 0);
        if (p.tok) { p.tok.textContent = n === 0 ? "" : n <= 3 ? "●".repeat(n) : String(n); }
      });
      charts.forEach(function (c) {
        if (c.cursor) {
          var x = c.px(k * ro.dt).toFixed(1);
          c.cursor.setAttribute("x1", x);
          c.cursor.setAttribute("x2", x);
        }
      });
      label.textContent = "step " + k + " / " + ro.steps + ", t = " + (k * ro.dt).toFixed(3) + " s";
      document.documentElement.setAttribute("data-step", String(k));
      document.documentElement.setAttribute("data-run", String(state.run));
    }

    function chooseRun(r) {
      state.run = r;
      choose.value = String(r);
      drawRun(r);
      setStep(state.step);
    }

    function stop() {
      if (state.timer !== null) { clearInterval(state.timer); state.timer = null; play.textContent = "▶ play"; }
    }

    slider.max = String(ro.steps);
    slider.addEventListener("input", function () { setStep(+slider.value); });
    choose.addEventListener("change", function () { chooseRun(+choose.value); });
    play.addEventListener("click", function () {
      if (state.timer !== null) { stop(); return; }
      if (state.step >= ro.steps) { slider.value = "0"; setStep(0); }
      play.textContent = "❚❚ pause";
      state.timer = setInterval(function () {
        if (state.step >= ro.steps) { stop(); return; }
        slider.value = String(state.step + 1);
        slider.dispatchEvent(new Event("input"));
      }, Math.max(15, Math.min(120, 6000 / ro.steps)));
    });
    document.querySelectorAll("tr.run-row").forEach(function (tr) {
      tr.addEventListener("click", function () { stop(); chooseRun(+tr.getAttribute("data-run")); });
    });

    var hash = {};
    location.hash.replace(/^#/, "").split("&").forEach(function (kv) {
      var p = kv.split("=");
      if (p.length === 2) { hash[p[0]] = p[1]; }
    });
    var first = hash.run !== undefined ? +hash.run : 0;
    chooseRun(first >= 0 && first < ro.runs.length ? first : 0);
    if (hash.step !== undefined) {  // as a user moving the slider: its value, then its input event
      slider.value = hash.step;
      slider.dispatchEvent(new Event("input"));
    } else {
      slider.value = "0";
      setStep(0);
    }
  }
  document.documentElement.setAttribute("data-ready", "1");
})();
