// vagsl report viewer: WebGL2 renderer of the trained Gaussians and of the mesh.
//
// It draws a scene view the way gs-raster does (docs/method.md §Rendering): camera-space mean
// t = R μ + t_c, culled at z ≤ near; Σ' = J R Σ Rᵀ Jᵀ + the run's low-pass filter (px²) with
// t_x/t_z and t_y/t_z clamped to ±1.3·tan(fov/2); with the run's antialiasing, o scaled by
// max(√(det Σ'_raw / det Σ'), 0.005) (near, filter, clamp and floor from the page's
// `splats.projection`, which gs-report fills from the run's RasterConfig); α = min(0.99, o·exp(−½ dᵀΣ'⁻¹d)), skipped below 1/255; colour
// max(SH(d) + 0.5, 0) along d = (μ − C)/‖μ − C‖; blended in depth order over the background.
// Blending runs back to front with premultiplied alpha (the "over" operator), which equals the
// rasterizer's front-to-back sum; it accumulates in a half-float framebuffer when the browser
// offers one, then is copied to the canvas.
"use strict";

function b64Bytes(s) {
  const bin = atob(s);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}
const b64F32 = (s) => new Float32Array(b64Bytes(s).buffer);
const b64U32 = (s) => new Uint32Array(b64Bytes(s).buffer);

const TEX_W = 4096;

const SPLAT_VS = `#version 300 es
precision highp float; precision highp int; precision highp sampler2D;
uniform sampler2D u_geo; uniform sampler2D u_sh;
uniform mat3 u_R; uniform vec3 u_t; uniform vec3 u_C;
uniform vec4 u_K; uniform vec2 u_size; uniform vec2 u_lim;
uniform float u_near; uniform float u_lowPass; uniform float u_minComp; uniform bool u_aa;
uniform int u_shTexels; uniform int u_degree;
in vec2 a_corner; in uint a_index;
out vec3 v_color; out float v_opacity; out vec3 v_conic; out vec2 v_center; out float v_sigmaMax;
ivec2 at(int i) { return ivec2(i % ${TEX_W}, i / ${TEX_W}); }
vec3 shc(int base, int k) {
  int f = k * 3;
  vec4 a = texelFetch(u_sh, at(base + f / 4), 0);
  vec4 b = texelFetch(u_sh, at(base + (f + 2) / 4), 0);
  int r = f % 4;
  if (r == 0) return a.xyz;
  if (r == 1) return a.yzw;
  if (r == 2) return vec3(a.z, a.w, b.x);
  return vec3(a.w, b.x, b.y);
}
vec3 shColor(int i, vec3 d) {
  int base = i * u_shTexels;
  vec3 c = 0.28209479 * shc(base, 0);
  if (u_degree >= 1) {
    float x = d.x, y = d.y, z = d.z;
    c += -0.48860251 * y * shc(base, 1) + 0.48860251 * z * shc(base, 2) - 0.48860251 * x * shc(base, 3);
    if (u_degree >= 2) {
      float xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
      c += 1.0925484 * xy * shc(base, 4) - 1.0925484 * yz * shc(base, 5)
        + 0.31539157 * (2.0 * zz - xx - yy) * shc(base, 6) - 1.0925484 * xz * shc(base, 7)
        + 0.5462742 * (xx - yy) * shc(base, 8);
      if (u_degree >= 3) {
        c += -0.5900436 * y * (3.0 * xx - yy) * shc(base, 9) + 2.8906114 * xy * z * shc(base, 10)
          - 0.4570458 * y * (4.0 * zz - xx - yy) * shc(base, 11)
          + 0.37317633 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * shc(base, 12)
          - 0.4570458 * x * (4.0 * zz - xx - yy) * shc(base, 13) + 1.4453057 * z * (xx - yy) * shc(base, 14)
          - 0.5900436 * x * (xx - 3.0 * yy) * shc(base, 15);
      }
    }
  }
  return max(c + 0.5, 0.0);
}
void main() {
  int i = int(a_index);
  vec4 g0 = texelFetch(u_geo, at(3 * i), 0);
  vec4 g1 = texelFetch(u_geo, at(3 * i + 1), 0);
  vec4 g2 = texelFetch(u_geo, at(3 * i + 2), 0);
  vec3 t = u_R * g0.xyz + u_t;
  gl_Position = vec4(0.0, 0.0, 2.0, 1.0);
  float op = g0.w;
  if (!(t.z > u_near) || op < 1.0 / 255.0) return;
  mat3 S = mat3(g1.x, g1.y, g1.z, g1.y, g1.w, g2.x, g1.z, g2.x, g2.y);
  float iz = 1.0 / t.z;
  float cx = clamp(t.x * iz, -u_lim.x, u_lim.x), cy = clamp(t.y * iz, -u_lim.y, u_lim.y);
  mat3 J = mat3(u_K.x * iz, 0.0, 0.0, 0.0, u_K.y * iz, 0.0, -u_K.x * cx * iz, -u_K.y * cy * iz, 0.0);
  mat3 T = J * u_R;
  mat3 V = T * S * transpose(T);
  float a = V[0][0] + u_lowPass, b = V[0][1], c = V[1][1] + u_lowPass;
  float det = a * c - b * b;
  if (!(det > 0.0)) return;
  if (u_aa) {
    float ratio = (V[0][0] * V[1][1] - b * b) / det;
    op *= ratio > u_minComp * u_minComp ? sqrt(ratio) : u_minComp;
    if (op < 1.0 / 255.0) return;
  }
  vec2 center = vec2(u_K.x * t.x * iz + u_K.z, u_K.y * t.y * iz + u_K.w);
  float sigmaMax = log(op * 255.0);
  float level = sqrt(max(2.0 * sigmaMax, 0.0));
  vec2 ext = level * sqrt(vec2(a, c)) + 1.0;
  vec2 p = center + a_corner * ext;
  gl_Position = vec4(2.0 * p.x / u_size.x - 1.0, 1.0 - 2.0 * p.y / u_size.y, 0.0, 1.0);
  v_center = center;
  v_conic = vec3(c, -b, a) / det;
  v_opacity = op;
  v_sigmaMax = sigmaMax;
  v_color = shColor(i, normalize(g0.xyz - u_C));
}`;

const SPLAT_FS = `#version 300 es
precision highp float;
uniform vec2 u_size;
in vec3 v_color; in float v_opacity; in vec3 v_conic; in vec2 v_center; in float v_sigmaMax;
out vec4 o;
void main() {
  vec2 d = vec2(gl_FragCoord.x, u_size.y - gl_FragCoord.y) - v_center;
  float s = 0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) + v_conic.y * d.x * d.y;
  if (!(s >= 0.0 && s <= v_sigmaMax)) discard;
  float alpha = v_opacity * exp(-s);
  if (alpha < 1.0 / 255.0) discard;
  alpha = min(alpha, 0.99);
  o = vec4(v_color * alpha, alpha);
}`;

const MESH_VS = `#version 300 es
precision highp float;
uniform mat3 u_R; uniform vec3 u_t; uniform vec4 u_K; uniform vec2 u_size; uniform vec2 u_nf;
in vec3 a_pos; in vec3 a_normal;
out vec3 v_n; out vec3 v_cam;
void main() {
  vec3 t = u_R * a_pos + u_t;
  float n = u_nf.x, f = u_nf.y;
  gl_Position = vec4(2.0 * u_K.x / u_size.x * t.x + (2.0 * u_K.z / u_size.x - 1.0) * t.z,
                     -2.0 * u_K.y / u_size.y * t.y + (1.0 - 2.0 * u_K.w / u_size.y) * t.z,
                     (f + n) / (f - n) * t.z - 2.0 * f * n / (f - n), t.z);
  v_n = u_R * a_normal;
  v_cam = t;
}`;

const MESH_FS = `#version 300 es
precision highp float;
in vec3 v_n; in vec3 v_cam;
out vec4 o;
void main() {
  float shade = 0.15 + 0.8 * abs(dot(normalize(v_n), normalize(v_cam)));
  o = vec4(shade * vec3(0.92, 0.9, 0.85), 1.0);
}`;

const COPY_VS = `#version 300 es
in vec2 a_corner; out vec2 v_uv;
void main() { v_uv = a_corner * 0.5 + 0.5; gl_Position = vec4(a_corner, 0.0, 1.0); }`;
const COPY_FS = `#version 300 es
precision highp float; uniform sampler2D u_img; in vec2 v_uv; out vec4 o;
void main() { o = vec4(clamp(texture(u_img, v_uv).rgb, 0.0, 1.0), 1.0); }`;

function compile(gl, vs, fs) {
  const prog = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
    const sh = gl.createShader(type);
    gl.shaderSource(sh, src);
    gl.compileShader(sh);
    if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(sh));
    gl.attachShader(prog, sh);
  }
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(prog));
  return prog;
}

function floatTexture(gl, data, texelsPerItem, count) {
  const texels = texelsPerItem * count;
  const rows = Math.max(1, Math.ceil(texels / TEX_W));
  const padded = new Float32Array(TEX_W * rows * 4);
  padded.set(data.subarray(0, Math.min(data.length, padded.length)));
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, TEX_W, rows, 0, gl.RGBA, gl.FLOAT, padded);
  for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
  return tex;
}

// Ascending LSD radix sort of `ids` by their positive float `depth[id]` (whose bit patterns
// order like the values); returns the permutation.
function sortByDepth(depth, ids) {
  const n = ids.length;
  const keys = new Uint32Array(depth.buffer, depth.byteOffset, depth.length);
  let a = ids, b = new Uint32Array(n);
  const count = new Uint32Array(256);
  for (let shift = 0; shift < 32; shift += 8) {
    count.fill(0);
    for (let i = 0; i < n; i++) count[(keys[a[i]] >>> shift) & 255]++;
    let sum = 0;
    for (let k = 0; k < 256; k++) { const c = count[k]; count[k] = sum; sum += c; }
    for (let i = 0; i < n; i++) { const id = a[i]; b[count[(keys[id] >>> shift) & 255]++] = id; }
    [a, b] = [b, a];
  }
  return a;
}

class Viewer {
  constructor(canvas, page) {
    this.canvas = canvas;
    const gl = canvas.getContext("webgl2", { antialias: false, alpha: false, preserveDrawingBuffer: true });
    if (!gl) throw new Error("this browser offers no WebGL2; the viewer needs it");
    this.gl = gl;
    this.background = page.background;
    this.mode = "splats";
    this.splats = page.splats;
    this.splatProg = compile(gl, SPLAT_VS, SPLAT_FS);
    this.copyProg = compile(gl, COPY_VS, COPY_FS);
    this.geo = b64F32(page.splats.geo);
    this.shTexels = Math.ceil((3 * page.splats.sh_coeffs) / 4);
    this.geoTex = floatTexture(gl, this.geo, 3, page.splats.count);
    this.shTex = floatTexture(gl, b64F32(page.splats.sh), this.shTexels, page.splats.count);
    this.quad = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.quad);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
    this.indexBuf = gl.createBuffer();
    this.splatVao = gl.createVertexArray();
    gl.bindVertexArray(this.splatVao);
    this.bindCorner(this.splatProg);
    const ai = gl.getAttribLocation(this.splatProg, "a_index");
    gl.bindBuffer(gl.ARRAY_BUFFER, this.indexBuf);
    gl.enableVertexAttribArray(ai);
    gl.vertexAttribIPointer(ai, 1, gl.UNSIGNED_INT, 0, 0);
    gl.vertexAttribDivisor(ai, 1);
    this.copyVao = gl.createVertexArray();
    gl.bindVertexArray(this.copyVao);
    this.bindCorner(this.copyProg);
    gl.bindVertexArray(null);
    this.floatTarget = !!gl.getExtension("EXT_color_buffer_float");
    this.depth = new Float32Array(page.splats.count);
    this.ids = new Uint32Array(page.splats.count);
    this.visible = 0;
    this.sortedFor = null;
    if (page.mesh) this.initMesh(page.mesh);
  }

  bindCorner(prog) {
    const gl = this.gl;
    const loc = gl.getAttribLocation(prog, "a_corner");
    gl.bindBuffer(gl.ARRAY_BUFFER, this.quad);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
  }

  initMesh(mesh) {
    const gl = this.gl;
    this.meshProg = compile(gl, MESH_VS, MESH_FS);
    this.meshVao = gl.createVertexArray();
    gl.bindVertexArray(this.meshVao);
    for (const [name, b64] of [["a_pos", mesh.positions], ["a_normal", mesh.normals]]) {
      const buf = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buf);
      gl.bufferData(gl.ARRAY_BUFFER, b64F32(b64), gl.STATIC_DRAW);
      const loc = gl.getAttribLocation(this.meshProg, name);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    }
    const ibuf = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibuf);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, b64U32(mesh.indices), gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    this.meshCount = mesh.triangles * 3;
    const p = b64F32(mesh.positions);
    this.meshCenter = [0, 1, 2].map((k) => { let s = 0; for (let i = k; i < p.length; i += 3) s += p[i]; return s / (p.length / 3); });
  }

  // Depth order of the Gaussians in front of the near plane for camera `cam` (far first).
  sort(cam) {
    const R = cam.R, t = cam.t, g = this.geo, n = this.splats.count;
    let m = 0;
    for (let i = 0; i < n; i++) {
      const z = R[6] * g[12 * i] + R[7] * g[12 * i + 1] + R[8] * g[12 * i + 2] + t[2];
      this.depth[i] = z;
      if (z > 0.01) this.ids[m++] = i;
    }
    const order = sortByDepth(this.depth, this.ids.slice(0, m)).reverse();
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.indexBuf);
    gl.bufferData(gl.ARRAY_BUFFER, order, gl.DYNAMIC_DRAW);
    this.visible = m;
  }

  target(w, h) {
    const gl = this.gl;
    if (!this.floatTarget) return null;
    if (this.fbo && this.fboSize[0] === w && this.fboSize[1] === h) return this.fbo;
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA16F, w, h, 0, gl.RGBA, gl.HALF_FLOAT, null);
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
    this.fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) {
      this.floatTarget = false;
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      return null;
    }
    this.fboTex = tex;
    this.fboSize = [w, h];
    return this.fbo;
  }

  // Draws camera `cam` = {R (row-major world→camera), t, fx, fy, cx, cy, width, height}.
  draw(cam) {
    const gl = this.gl, w = this.canvas.width, h = this.canvas.height;
    const Rcm = [cam.R[0], cam.R[3], cam.R[6], cam.R[1], cam.R[4], cam.R[7], cam.R[2], cam.R[5], cam.R[8]];
    const K = [cam.fx, cam.fy, cam.cx, cam.cy];
    if (this.mode === "mesh" && this.meshProg) return this.drawMesh(cam, Rcm, K, w, h);
    const key = cam.R.join() + cam.t.join();
    if (this.sortedFor !== key) { this.sort(cam); this.sortedFor = key; }
    const fbo = this.target(w, h);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.viewport(0, 0, w, h);
    const bg = this.background;
    gl.clearColor(bg[0], bg[1], bg[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.disable(gl.DEPTH_TEST);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
    const p = this.splatProg;
    gl.useProgram(p);
    const C = [0, 1, 2].map((k) => -(cam.R[k] * cam.t[0] + cam.R[3 + k] * cam.t[1] + cam.R[6 + k] * cam.t[2]));
    gl.uniformMatrix3fv(gl.getUniformLocation(p, "u_R"), false, Rcm);
    gl.uniform3fv(gl.getUniformLocation(p, "u_t"), cam.t);
    gl.uniform3fv(gl.getUniformLocation(p, "u_C"), C);
    gl.uniform4fv(gl.getUniformLocation(p, "u_K"), K);
    gl.uniform2f(gl.getUniformLocation(p, "u_size"), w, h);
    const proj = this.splats.projection;
    gl.uniform2f(gl.getUniformLocation(p, "u_lim"), proj.jacobian_clamp * (0.5 * w / cam.fx), proj.jacobian_clamp * (0.5 * h / cam.fy));
    gl.uniform1f(gl.getUniformLocation(p, "u_near"), proj.near);
    gl.uniform1f(gl.getUniformLocation(p, "u_lowPass"), proj.low_pass);
    gl.uniform1f(gl.getUniformLocation(p, "u_minComp"), proj.min_compensation);
    gl.uniform1i(gl.getUniformLocation(p, "u_aa"), proj.antialiased ? 1 : 0);
    gl.uniform1i(gl.getUniformLocation(p, "u_shTexels"), this.shTexels);
    gl.uniform1i(gl.getUniformLocation(p, "u_degree"), this.splats.sh_degree);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.geoTex);
    gl.uniform1i(gl.getUniformLocation(p, "u_geo"), 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, this.shTex);
    gl.uniform1i(gl.getUniformLocation(p, "u_sh"), 1);
    gl.bindVertexArray(this.splatVao);
    gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, this.visible);
    gl.disable(gl.BLEND);
    if (fbo) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.useProgram(this.copyProg);
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, this.fboTex);
      gl.uniform1i(gl.getUniformLocation(this.copyProg, "u_img"), 0);
      gl.bindVertexArray(this.copyVao);
      gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
    }
    gl.bindVertexArray(null);
  }

  drawMesh(cam, Rcm, K, w, h) {
    const gl = this.gl, p = this.meshProg;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, w, h);
    gl.clearColor(0, 0, 0, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.disable(gl.BLEND);
    gl.useProgram(p);
    gl.uniformMatrix3fv(gl.getUniformLocation(p, "u_R"), false, Rcm);
    gl.uniform3fv(gl.getUniformLocation(p, "u_t"), cam.t);
    gl.uniform4fv(gl.getUniformLocation(p, "u_K"), K);
    gl.uniform2f(gl.getUniformLocation(p, "u_size"), w, h);
    gl.uniform2f(gl.getUniformLocation(p, "u_nf"), cam.near, cam.far);
    gl.bindVertexArray(this.meshVao);
    gl.drawElements(gl.TRIANGLES, this.meshCount, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }
}

window.VagslViewer = Viewer;
