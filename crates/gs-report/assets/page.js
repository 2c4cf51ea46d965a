// vagsl report page: wires the viewer to the scene's cameras (list, URL fragment
// #view=NAME, orbit / fly controls), and draws the views table, the curves and the results.
// It records its state in <body data-status="..."> (ready, errors) for headless tests.
"use strict";

const status = { ready: false, errors: [], view: null, frames: 0 };
function report() { document.body.dataset.status = JSON.stringify(status); }
window.addEventListener("error", (e) => { status.errors.push(String(e.message)); report(); });
window.addEventListener("unhandledrejection", (e) => { status.errors.push(String(e.reason)); report(); });
const consoleError = console.error.bind(console);
console.error = (...args) => { status.errors.push(args.map(String).join(" ")); report(); consoleError(...args); };

const $ = (sel) => document.querySelector(sel);
function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "onclick") e.addEventListener("click", v); else e.setAttribute(k, v);
  }
  for (const c of children) e.append(c);
  return e;
}
const fmt = (v, d) => (v === null || v === undefined ? "—" : Number(v).toFixed(d));

// ---- camera maths (world→camera R row-major, centre C) ----
function mul3(A, B) {
  const o = new Array(9).fill(0);
  for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) for (let k = 0; k < 3; k++) o[3 * r + c] += A[3 * r + k] * B[3 * k + c];
  return o;
}
const transpose3 = (A) => [A[0], A[3], A[6], A[1], A[4], A[7], A[2], A[5], A[8]];
const apply3 = (A, v) => [0, 1, 2].map((r) => A[3 * r] * v[0] + A[3 * r + 1] * v[1] + A[3 * r + 2] * v[2]);
function axisAngle(a, th) {
  const [x, y, z] = a, c = Math.cos(th), s = Math.sin(th), C = 1 - c;
  return [c + x * x * C, x * y * C - z * s, x * z * C + y * s, y * x * C + z * s, c + y * y * C, y * z * C - x * s, z * x * C - y * s, z * y * C + x * s, c + z * z * C];
}
const centreOf = (R, t) => apply3(transpose3(R), t).map((v) => -v);
const translationOf = (R, C) => apply3(R, C).map((v) => -v);

function main() {
  const data = window.VAGSL_DATA;
  if (!data) throw new Error("report/data.js did not load: keep report.html beside its report/ folder");
  const page = data.page, views = data.views;
  document.title = page.title;
  $("#title").textContent = page.title;
  const facts = $("#facts");
  for (const [k, v] of page.facts) facts.append(el("tr", {}, el("th", {}, k), el("td", {}, v)));
  // The views, curves and results first: a browser without WebGL2 still shows them.
  drawViews(views);
  drawCurves(page.curves);
  drawResults(page);

  const canvas = $("#viewer");
  const viewer = new window.VagslViewer(canvas, page);
  const geo = viewer.geo, n = page.splats.count;
  const med = [0, 1, 2].map((k) => { const a = []; for (let i = 0; i < n; i += Math.max(1, Math.floor(n / 5000))) a.push(geo[12 * i + k]); a.sort((x, y) => x - y); return a.length ? a[a.length >> 1] : 0; });
  let target = viewer.meshCenter || med;
  let cam = null, base = null, only = false;

  function resize() {
    const s = only ? 1 : Math.max(1, Math.min(960, $("#viewer-box").clientWidth)) / base.width;
    canvas.width = Math.round(base.width * s);
    canvas.height = Math.round(base.height * s);
    cam.fx = base.fx * s; cam.fy = base.fy * s; cam.cx = base.cx * s; cam.cy = base.cy * s;
    canvas.style.width = canvas.width + "px";
    canvas.style.height = canvas.height + "px";
  }
  let pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      const dist = Math.hypot(...cam.C.map((c, k) => c - target[k]));
      viewer.draw({ ...cam, t: translationOf(cam.R, cam.C), near: Math.max(1e-3, dist * 1e-3), far: dist * 1e3 });
      status.frames++;
      if (!status.ready) { status.ready = true; }
      report();
    });
  }
  function select(name) {
    const v = views.find((x) => x.camera.name === name) || views[0];
    base = v.camera;
    cam = { R: base.r.slice(), C: centreOf(base.r, base.t) };
    status.view = base.name;
    $("#view-select").value = base.name;
    $("#view-name").textContent = `${base.name} (${base.split === "test" ? "held-out" : "training"} view, ${base.width} × ${base.height} px)`;
    resize();
    redraw();
  }
  function fromHash() {
    const h = new URLSearchParams(location.hash.slice(1));
    only = h.has("viewer");
    document.body.classList.toggle("viewer-only", only);
    if (h.get("mode") === "mesh" && viewer.meshProg) setMode("mesh");
    select(h.get("view") || (views.find((v) => v.camera.split === "test") || views[0]).camera.name);
  }
  function setMode(m) {
    viewer.mode = m;
    $("#mode").textContent = m === "mesh" ? "show splats" : "show mesh";
    redraw();
  }

  const sel = $("#view-select");
  for (const v of views) sel.append(el("option", { value: v.camera.name }, `${v.camera.name} (${v.camera.split})`));
  sel.addEventListener("change", () => { location.hash = "view=" + encodeURIComponent(sel.value); });
  window.addEventListener("hashchange", fromHash);
  if (page.mesh) {
    $("#mode").addEventListener("click", () => setMode(viewer.mode === "mesh" ? "splats" : "mesh"));
  } else {
    $("#mode").disabled = true;
    $("#mode").title = "no mesh yet: run `vagsl mesh RUN`, then `vagsl view RUN` again";
  }

  // Orbit (drag) about the scene centre, pan (shift-drag or right-drag), dolly (wheel), fly (W A S D Q E).
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => { drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 }; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener("pointerup", () => { drag = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    const dist = Math.hypot(...cam.C.map((c, k) => c - target[k]));
    if (drag.pan) {
      const s = dist / cam.fx;
      for (let k = 0; k < 3; k++) { const d = -dx * s * cam.R[k] - dy * s * cam.R[3 + k]; cam.C[k] += d; target[k] += d; }
    } else {
      for (const [axis, ang] of [[[-cam.R[3], -cam.R[4], -cam.R[5]], -dx * 0.005], [[cam.R[0], cam.R[1], cam.R[2]], dy * 0.005]]) {
        const Q = axisAngle(axis, ang);
        const rel = apply3(Q, cam.C.map((c, k) => c - target[k]));
        cam.C = rel.map((r, k) => r + target[k]);
        cam.R = mul3(cam.R, transpose3(Q));
      }
    }
    redraw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const f = Math.exp(Math.max(-100, Math.min(100, e.deltaY)) * 0.002);
    cam.C = cam.C.map((c, k) => target[k] + (c - target[k]) * f);
    redraw();
  }, { passive: false });
  window.addEventListener("keydown", (e) => {
    const axes = { w: [2, 1], s: [2, -1], d: [0, 1], a: [0, -1], e: [1, -1], q: [1, 1] }[e.key.toLowerCase()];
    if (!axes || e.target.tagName === "SELECT") return;
    const dist = Math.hypot(...cam.C.map((c, k) => c - target[k]));
    const step = 0.03 * dist * axes[1];
    for (let k = 0; k < 3; k++) { const d = step * cam.R[3 * axes[0] + k]; cam.C[k] += d; target[k] += d; }
    redraw();
  });
  window.addEventListener("resize", () => { if (base) { resize(); redraw(); } });

  fromHash();
}

function drawViews(views) {
  const body = $("#views tbody");
  for (const v of views) {
    const s = v.scores;
    const pick = el("a", { href: "#view=" + encodeURIComponent(v.camera.name), title: "show this camera in the viewer" }, v.camera.name);
    const img = (src, alt) => el("td", {}, el("a", { href: src }, el("img", { src, alt, loading: "lazy", width: 200 })));
    body.append(el("tr", { class: v.camera.split },
      el("td", {}, pick, el("br"), v.camera.split === "test" ? "held-out" : "training"),
      el("td", { class: "num" }, s ? `${fmt(s.psnr, 2)} dB` : "—", el("br"), s ? `SSIM ${fmt(s.ssim, 4)}` : "", el("br"), s && s.lpips !== null ? `LPIPS ${fmt(s.lpips, 4)}` : "", s && s.note ? el("div", { class: "note" }, s.note) : ""),
      img(v.photo, "photo"), img(v.render, "render"), img(v.normal, "normal map"), img(v.depth, "depth map")));
  }
  const test = views.filter((v) => v.camera.split === "test" && v.scores);
  if (test.length) {
    const mean = (f) => test.reduce((a, v) => a + f(v.scores), 0) / test.length;
    $("#views-summary").textContent = `Held-out views: mean PSNR ${fmt(mean((s) => s.psnr), 2)} dB, SSIM ${fmt(mean((s) => s.ssim), 4)} over ${test.length} views.`;
  }
}

// A line plot as SVG: series = [{name, points: [[x, y]], color}].
function plot(title, xLabel, series, logY) {
  const W = 460, H = 260, L = 60, B = 40, T = 24, Rm = 12;
  const pts = series.flatMap((s) => s.points).filter((p) => isFinite(p[1]) && (!logY || p[1] > 0));
  const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
  svg.setAttribute("width", W); svg.setAttribute("height", H); svg.setAttribute("class", "plot");
  const add = (tag, attrs, text) => {
    const e = document.createElementNS("http://www.w3.org/2000/svg", tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    svg.append(e);
    return e;
  };
  add("text", { x: L, y: 16, class: "title" }, title);
  if (!pts.length) { add("text", { x: L, y: H / 2 }, "no data"); return svg; }
  const fy = logY ? Math.log10 : (v) => v;
  let [x0, x1] = [Math.min(...pts.map((p) => p[0])), Math.max(...pts.map((p) => p[0]))];
  let [y0, y1] = [Math.min(...pts.map((p) => fy(p[1]))), Math.max(...pts.map((p) => fy(p[1])))];
  if (x1 <= x0) x1 = x0 + 1;
  if (y1 <= y0) { y1 = y0 + 1; y0 -= 1; }
  const X = (x) => L + ((x - x0) / (x1 - x0)) * (W - L - Rm), Y = (y) => H - B - ((fy(y) - y0) / (y1 - y0)) * (H - B - T);
  add("line", { x1: L, y1: H - B, x2: W - Rm, y2: H - B, class: "axis" });
  add("line", { x1: L, y1: T, x2: L, y2: H - B, class: "axis" });
  for (let i = 0; i <= 4; i++) {
    const xv = x0 + ((x1 - x0) * i) / 4, yv = y0 + ((y1 - y0) * i) / 4;
    add("text", { x: X(xv), y: H - B + 16, "text-anchor": "middle" }, xv.toPrecision(3));
    add("text", { x: L - 6, y: H - B - ((yv - y0) / (y1 - y0)) * (H - B - T) + 4, "text-anchor": "end" }, (logY ? 10 ** yv : yv).toPrecision(3));
  }
  add("text", { x: (L + W) / 2, y: H - 6, "text-anchor": "middle" }, xLabel);
  series.forEach((s, j) => {
    const p = s.points.filter((q) => isFinite(q[1]) && (!logY || q[1] > 0));
    if (!p.length) return;
    add("polyline", { points: p.map((q) => `${X(q[0]).toFixed(1)},${Y(q[1]).toFixed(1)}`).join(" "), fill: "none", stroke: s.color, "stroke-width": 1.5 });
    if (p.length < 40) p.forEach((q) => add("circle", { cx: X(q[0]), cy: Y(q[1]), r: 2.5, fill: s.color }));
    add("text", { x: W - Rm - 4, y: T + 14 * (j + 1), "text-anchor": "end", fill: s.color }, s.name);
  });
  return svg;
}

function drawCurves(curves) {
  const box = $("#curves");
  if (!curves.length) { box.append(el("p", {}, "No training curves: this run predates metrics.jsonl.")); return; }
  const steps = curves.filter((c) => c.loss);
  const series = (f) => steps.map((c) => [c.seconds, f(c)]).filter((p) => p[1] !== null && p[1] !== undefined);
  const losses = [["total", "#1f77b4", (c) => c.loss.total], ["L1", "#ff7f0e", (c) => c.loss.l1], ["L_p", "#2ca02c", (c) => c.loss.photometric], ["L_f", "#d62728", (c) => c.loss.features]];
  box.append(plot("Training loss", "training time (s)", losses.map(([name, color, f]) => ({ name, color, points: series(f) })), true));
  box.append(plot("Gaussians", "training time (s)", [{ name: "Gaussians", color: "#9467bd", points: series((c) => c.gaussians) }], false));
  const held = curves.filter((c) => c.heldout_psnr !== undefined).map((c) => [c.seconds, c.heldout_psnr]);
  if (held.length) box.append(plot("Held-out PSNR (dB)", "training time (s)", [{ name: "PSNR", color: "#8c564b", points: held }], false));
  // `train --track-gt`: the mesh scored against the ground truth at the same points.
  const mesh = curves.filter((c) => c.chamfer !== undefined).map((c) => [c.seconds, c.chamfer]);
  if (mesh.length) box.append(plot("Mesh Chamfer vs ground truth", "training time (s)", [{ name: "Chamfer", color: "#17becf", points: mesh }], true));
}

function drawResults(page) {
  const box = $("#results");
  if (page.mesh) box.append(el("p", {}, `Mesh: ${page.mesh.source_triangles.toLocaleString()} triangles` + (page.mesh.triangles < page.mesh.source_triangles ? ` (shown simplified to ${page.mesh.triangles.toLocaleString()})` : "") + "."));
  else box.append(el("p", {}, "No mesh yet: run `vagsl mesh RUN`, then `vagsl view RUN` again."));
  if (page.mesh_metrics) {
    const t = el("table", { class: "facts" });
    for (const [k, v] of Object.entries(page.mesh_metrics)) if (typeof v === "number") t.append(el("tr", {}, el("th", {}, k.replaceAll("_", " ")), el("td", {}, Math.abs(v) < 1e-2 && v !== 0 ? v.toExponential(3) : String(+v.toPrecision(5)))));
    box.append(el("h3", {}, "Mesh against ground truth (vagsl eval-mesh)"), t);
  }
  if (page.tradeoff_svg) {
    const d = el("div", { class: "tradeoff" });
    d.innerHTML = page.tradeoff_svg;
    box.append(el("h3", {}, "Speed / accuracy tradeoff (vagsl tradeoff)"), d);
  }
}

try { main(); } catch (e) { status.errors.push(String(e && e.message ? e.message : e)); report(); const m = document.querySelector("#error"); if (m) { m.textContent = "The viewer could not start: " + e.message; m.hidden = false; } }
