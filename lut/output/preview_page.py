"""The HTML page of the 3D preview: controls, the embedded plotly.js bundle and the player script.

The player (plain JavaScript, no other library) moves each mesh by its body's 3×4 pose of the current
frame (``world = R · local + p``) and restyles the plotly traces in place, so the camera the user set is
kept. It reads the start time from the URL (``?t=20`` or ``#t=20``, s since the observation) and
``play=1``; ``window.lutgenPreview`` exposes ``setTime``/``setFrame`` for scripted use.
"""

from __future__ import annotations

import html
import re

PLAYER_JS = r"""
(function () {
  "use strict";
  const gd = document.getElementById("scene");
  const F = DATA.frames, n = F.t.length, NB = DATA.n_bodies;
  const slider = document.getElementById("slider"), playBtn = document.getElementById("play");
  const speedSel = document.getElementById("speed"), timeEl = document.getElementById("time");
  const infoEl = document.getElementById("info");
  let current = -1, playing = false, simT = F.t[0], lastTs = null;

  function moveMesh(m, P) {
    const L = m.local, B = m.body, nv = B.length;
    const x = new Array(nv), y = new Array(nv), z = new Array(nv);
    for (let v = 0; v < nv; v++) {
      const o = B[v] * 12, lx = L[3 * v], ly = L[3 * v + 1], lz = L[3 * v + 2];
      x[v] = P[o] * lx + P[o + 1] * ly + P[o + 2] * lz + P[o + 3];
      y[v] = P[o + 4] * lx + P[o + 5] * ly + P[o + 6] * lz + P[o + 7];
      z[v] = P[o + 8] * lx + P[o + 9] * ly + P[o + 10] * lz + P[o + 11];
    }
    return [x, y, z];
  }

  function fmt(v, d) { return (v === null || v === undefined) ? "n/a" : Number(v).toFixed(d); }

  function setFrame(k) {
    k = Math.max(0, Math.min(n - 1, Math.round(k)));
    current = k;
    const P = F.poses[k], xs = [], ys = [], zs = [], traces = [];
    function push(trace, xyz) { traces.push(trace); xs.push(xyz[0]); ys.push(xyz[1]); zs.push(xyz[2]); }
    for (const m of DATA.meshes) push(m.trace, moveMesh(m, P));
    const sk = [[], [], []];  // joint origins of the chain, then the gripper's grasp frame
    for (const b of DATA.skeleton_bodies) for (let c = 0; c < 3; c++) sk[c].push(P[b * 12 + 4 * c + 3]);
    for (let c = 0; c < 3; c++) sk[c].push(F.ee[k][c]);
    push(DATA.dynamic.skeleton, sk);
    const G = F.grasp[k], len = DATA.axis_length_m;
    for (let a = 0; a < 3; a++) {
      push(DATA.dynamic.triad + a, [[G[3], G[3] + len * G[a]], [G[7], G[7] + len * G[4 + a]],
                                    [G[11], G[11] + len * G[8 + a]]]);
    }
    if (DATA.dynamic.closest !== undefined) {
      const C = F.closest_points[k];
      push(DATA.dynamic.closest, [[C[0], C[3]], [C[1], C[4]], [C[2], C[5]]]);
    }
    Plotly.restyle(gd, {x: xs, y: ys, z: zs}, traces);
    slider.value = k;
    timeEl.textContent = "t = " + fmt(F.t[k], 2) + " s";
    let info = F.phase[k] + " \u00b7 ";
    if (F.min_distance_m) {
      const d = F.min_distance_m[k];
      const low = DATA.margin_m !== null && d < DATA.margin_m;
      info += "min collision distance <b" + (low ? " class=\"low\"" : "") + ">" + fmt(d, 4) + " m</b>";
      if (F.closest_pair) info += " (" + escapeHtml(F.closest_pair[k]) + ")";
      if (DATA.margin_m !== null) info += ", margin " + fmt(DATA.margin_m, 3) + " m";
    } else {
      info += "min collision distance: not in this plan file (samples.min_distance_m)";
    }
    if (DATA.note) info += " \u00b7 <i>" + escapeHtml(DATA.note) + "</i>";
    infoEl.innerHTML = info;
    document.body.dataset.frame = String(k);
  }

  function escapeHtml(s) {
    return String(s).replace(/[&<>"]/g, function (c) {
      return {"&": "&amp;", "<": "&lt;", ">": "&gt;", "\"": "&quot;"}[c];
    });
  }

  function frameAt(t) {  // last frame with F.t <= t
    let lo = 0, hi = n - 1;
    while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (F.t[mid] <= t) lo = mid; else hi = mid - 1; }
    return lo;
  }

  function setTime(t) { simT = Math.max(F.t[0], Math.min(F.t[n - 1], t)); setFrame(frameAt(simT + 1e-9)); }

  function tick(ts) {
    if (!playing) return;
    if (lastTs !== null) simT += (ts - lastTs) / 1000 * Number(speedSel.value);
    lastTs = ts;
    if (simT >= F.t[n - 1]) { setFrame(n - 1); pause(); return; }
    const k = frameAt(simT);
    if (k !== current) setFrame(k);
    requestAnimationFrame(tick);
  }
  function play() {
    if (current >= n - 1) simT = F.t[0];
    playing = true; lastTs = null; playBtn.textContent = "\u275a\u275a pause"; requestAnimationFrame(tick);
  }
  function pause() { playing = false; playBtn.textContent = "\u25b6 play"; }

  playBtn.addEventListener("click", function () { if (playing) pause(); else play(); });
  slider.max = String(n - 1);
  slider.addEventListener("input", function () { pause(); simT = F.t[Number(slider.value)]; setFrame(slider.value); });

  const params = new URLSearchParams(location.search);
  new URLSearchParams(location.hash.replace(/^#/, "")).forEach(function (v, k) { params.set(k, v); });
  // the container's size, not plotly's default, and again whenever the window changes
  FIG.layout.width = gd.clientWidth; FIG.layout.height = gd.clientHeight;
  window.addEventListener("resize", function () {
    Plotly.relayout(gd, {width: gd.clientWidth, height: gd.clientHeight});
  });
  Plotly.newPlot(gd, FIG.data, FIG.layout, {displaylogo: false}).then(function () {
    const t = parseFloat(params.get("t"));
    if (isFinite(t)) setTime(t); else setFrame(0);
    if (params.get("play") === "1") play();
  });
  window.lutgenPreview = {setTime: setTime, setFrame: setFrame, frameCount: n, times: F.t};
})();
"""

PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>lutgen preview: __TITLE__</title>
<style>
  html, body { margin: 0; height: 100%; font-family: "DejaVu Sans", Arial, sans-serif; }
  #bar { display: flex; gap: 0.8em; align-items: center; padding: 6px 12px; background: #eef1f5;
         border-bottom: 1px solid #c8ced6; font-size: 14px; }
  #bar h1 { font-size: 15px; margin: 0 0.6em 0 0; white-space: nowrap; }
  #slider { flex: 1; }
  #time { font-family: "DejaVu Sans Mono", monospace; min-width: 9em; }
  #info { padding: 4px 12px; font-size: 13px; border-bottom: 1px solid #e2e6ea; min-height: 1.3em; }
  #info .low { color: #c81e1e; }
  #scene { position: absolute; top: 64px; bottom: 0; left: 0; right: 0; }
</style>
</head>
<body>
<div id="bar">
  <h1>__TITLE__</h1>
  <button id="play" type="button">&#9654; play</button>
  <input id="slider" type="range" min="0" max="0" value="0" step="1" aria-label="time">
  <span id="time"></span>
  <label>speed <select id="speed">
    <option value="1">1&times;</option><option value="2">2&times;</option>
    <option value="5" selected>5&times;</option><option value="10">10&times;</option>
  </select></label>
</div>
<div id="info"></div>
<div id="scene"></div>
<script type="text/javascript">__PLOTLYJS__</script>
<script type="text/javascript">
const FIG = __FIG__;
const DATA = __DATA__;
__PLAYER__
</script>
</body>
</html>
"""


def _script_safe(text: str) -> str:
    """JSON made safe inside <script>: a literal ``</`` would end the element early."""
    return text.replace("</", "<\\/")


def page_html(plotly_js: str, figure_json: str, data_json: str, title: str) -> str:
    """The complete page: ``plotly_js`` is the bundle's source, the JSONs are the figure and the frame data."""
    parts = {"__TITLE__": html.escape(title), "__FIG__": _script_safe(figure_json),
             "__DATA__": _script_safe(data_json), "__PLAYER__": PLAYER_JS, "__PLOTLYJS__": plotly_js}
    # one pass: text already inserted (user-named shapes, the bundle) is never searched for placeholders
    return re.sub(r"__(TITLE|FIG|DATA|PLAYER|PLOTLYJS)__", lambda m: parts[m.group(0)], PAGE)
