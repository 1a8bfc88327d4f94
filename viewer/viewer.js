// viewer.js - the page: loads the scene's encodings from `voxdag view`,
// ray casts them in WebGL2 (shader.js), orbit and fly cameras, a cut-depth
// slider, side-by-side views, statistics, screenshots. window.voxdag is
// the page's interface for tests/viewer/ (readBack with a camera file's
// camera gives render --voxel-id's and --depth's buffers).
import { decoders, formatOf, layoutOf, FormatError } from './formats.js';
import { vertexSource, fragmentSource } from './shader.js';

const $ = (id) => document.getElementById(id);
const status = (text, isError = false) => {
  const s = $('status');
  s.textContent = text;
  s.className = isError ? 'error' : '';
};

// ---------------------------------------------------------------- vectors
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = (a) => { const n = Math.sqrt(dot(a, a)); return n > 0 ? scale(a, 1 / n) : a; };

// The camera frame exactly as render's camera_frame() (doubles here too).
function frame(cam) {
  const fwd = norm(sub(cam.target, cam.eye));
  const right = norm(cross(fwd, cam.up));
  const up = cross(right, fwd);
  return { fwd, right, up, tanHalf: Math.tan((cam.fov * Math.PI) / 360) };
}

// ------------------------------------------------------------------- GL
class Renderer {
  constructor(canvas) {
    const gl = canvas.getContext('webgl2', { preserveDrawingBuffer: true, antialias: false });
    if (!gl) throw new Error('this browser has no WebGL2');
    this.gl = gl;
    this.maxTex = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    this.progDraw = this.program(false);
    this.progId = this.program(true);
    const vb = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vb);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
  }

  program(ids) {
    const gl = this.gl;
    const sh = (type, src) => {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS))
        throw new Error('shader: ' + gl.getShaderInfoLog(s));
      return s;
    };
    const p = gl.createProgram();
    gl.attachShader(p, sh(gl.VERTEX_SHADER, vertexSource));
    gl.attachShader(p, sh(gl.FRAGMENT_SHADER, fragmentSource(ids)));
    gl.bindAttribLocation(p, 0, 'aPos');
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('link: ' + gl.getProgramInfoLog(p));
    return p;
  }

  // Uploads a decoded scene's words as an R32UI texture 2^k texels wide;
  // refuses what the GPU cannot hold, saying which limit.
  upload(scene) {
    const gl = this.gl;
    const n = scene.words.length;
    let wlog = 0;
    while (1 << wlog < Math.min(this.maxTex, 4096)) wlog++;
    if (1 << wlog > this.maxTex) wlog--;
    const width = 1 << wlog;
    const rows = Math.max(1, Math.ceil(n / width));
    if (rows > this.maxTex)
      throw new Error(`${scene.name} needs a ${width} x ${rows} texture (${(4 * n / 2 ** 20).toFixed(1)} MB); ` +
        `this GPU allows ${this.maxTex} x ${this.maxTex} (MAX_TEXTURE_SIZE): too large to view here`);
    const data = new Uint32Array(width * rows);
    data.set(scene.words);
    const tex = this.texture(gl.R32UI, gl.RED_INTEGER, gl.UNSIGNED_INT, width, rows, data, scene.name);
    return { tex, wlog };
  }

  // A nearest-sampled 2D texture of width x rows texels from data.
  texture(internal, format, type, width, rows, data, name) {
    const gl = this.gl;
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, internal, width, rows, 0, format, type, data);
    const err = gl.getError();
    if (err) {
      gl.deleteTexture(tex);
      throw new Error(`${name}: texture upload failed (GL error ${err}); the GPU may be out of memory`);
    }
    return tex;
  }

  // A sampler2D must have a float texture bound even when unused.
  noColours() {
    if (!this.blank) {
      const gl = this.gl;
      this.blank = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, this.blank);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, 1, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
    }
    return this.blank;
  }

  // Uploads a colour array (3 bytes per voxel) as an RGB8 texture 4096
  // wide, which the shader indexes by the voxel's colour index.
  uploadColours(rgb, name) {
    const gl = this.gl;
    const n = rgb.length / 3, width = 4096;
    const rows = Math.max(1, Math.ceil(n / width));
    if (width > this.maxTex || rows > this.maxTex)
      throw new Error(`${name}: ${n} colours need a ${width} x ${rows} texture; ` +
        `this GPU allows ${this.maxTex} x ${this.maxTex} (MAX_TEXTURE_SIZE): too many to view here`);
    const data = new Uint8Array(3 * width * rows);
    data.set(rgb);
    return { tex: this.texture(gl.RGB8, gl.RGB, gl.UNSIGNED_BYTE, width, rows, data, name) };
  }

  setUniforms(p, view, cam, w, h, offset) {
    const gl = this.gl;
    const s = view.scene;
    const f = frame(cam);
    const u = (name) => gl.getUniformLocation(p, name);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, view.gpu.tex);
    gl.uniform1i(u('uData'), 0);
    gl.uniform1i(u('uTexWidthLog2'), view.gpu.wlog);
    gl.uniform1i(u('uL'), s.header.levels);
    gl.uniform1i(u('uCut'), Math.min(view.cut, s.header.levels));
    // render's lod_k: a node of side S voxels at distance t spans
    // S * voxelSize / (t * pixel angle) pixels
    gl.uniform1f(u('uLod'), (this.lod || 0) * 2 * f.tanHalf / h / s.voxelSize);
    const offs = new Uint32Array(22);
    s.levelOffsets.forEach((o, i) => { offs[i] = o; });
    gl.uniform1uiv(u('uLevelOff'), offs);
    gl.uniform1ui(u('uBrickBase'), s.brickBase);
    gl.uniform1ui(u('uCountBase'), s.countBase);
    gl.uniform1i(u('uFormat'), layoutOf(s));
    gl.uniform1i(u('uG48'), s.format === 'ssvdag48' ? 1 : 0);
    gl.uniform1ui(u('uCompBase'), s.compBase || 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, view.colours ? view.colours.tex : this.noColours());
    gl.uniform1i(u('uColours'), 1);
    gl.uniform1i(u('uHasColours'), view.colours ? 1 : 0);
    gl.uniform1i(u('uShade'), this.shade === false ? 0 : 1);
    gl.uniform3fv(u('uEye'), scale(sub(cam.eye, s.origin), 1 / s.voxelSize));
    gl.uniform3fv(u('uFwd'), f.fwd);
    gl.uniform3fv(u('uRight'), f.right);
    gl.uniform3fv(u('uUp'), f.up);
    gl.uniform1f(u('uInvVs'), 1 / s.voxelSize);
    gl.uniform1f(u('uTanHalf'), f.tanHalf);
    gl.uniform1f(u('uAspect'), w / h);
    gl.uniform2f(u('uSize'), w, h);
    gl.uniform2f(u('uOffset'), offset[0], offset[1]);
    const light = add(add(scale(f.right, -0.8), f.up), scale(f.fwd, -0.45));
    gl.uniform3fv(u('uLightDir'), light);
  }

  // Draws `view` into the canvas rectangle at (x, y) of size w x h.
  draw(view, cam, x, y, w, h) {
    const gl = this.gl;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.useProgram(this.progDraw);
    gl.viewport(x, y, w, h);
    this.setUniforms(this.progDraw, view, cam, w, h, [x, y]);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  // The id and depth buffers of `view` for cam at w x h, rows from the top
  // as render writes them: ids 4 u32 per pixel, depth float32.
  readBack(view, cam, w, h) {
    const gl = this.gl;
    const fb = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    const texs = [0, 1].map((i) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32UI, w, h);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, t, 0);
      return t;
    });
    gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1]);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE)
      throw new Error('cannot render to RGBA32UI targets here');
    gl.useProgram(this.progId);
    gl.viewport(0, 0, w, h);
    this.setUniforms(this.progId, view, cam, w, h, [0, 0]);
    gl.bindVertexArray(this.vao);
    const t0 = performance.now();
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    const raw = [new Uint32Array(4 * w * h), new Uint32Array(4 * w * h)];
    for (let i = 0; i < 2; i++) {
      gl.readBuffer(gl.COLOR_ATTACHMENT0 + i);
      gl.readPixels(0, 0, w, h, gl.RGBA_INTEGER, gl.UNSIGNED_INT, raw[i]);
    }
    const ms = performance.now() - t0;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(fb);
    texs.forEach((t) => gl.deleteTexture(t));
    const ids = new Uint32Array(4 * w * h);
    const depth = new Float32Array(w * h);
    const dbits = new Uint32Array(depth.buffer);
    for (let y = 0; y < h; y++) {
      const src = (h - 1 - y) * w, dst = y * w; // GL rows are bottom-up
      ids.set(raw[0].subarray(4 * src, 4 * (src + w)), 4 * dst);
      for (let x = 0; x < w; x++) dbits[dst + x] = raw[1][4 * (src + x)];
    }
    return { ids, depth, ms };
  }
}

// ---------------------------------------------------------------- loading
async function fetchWithProgress(url, onProgress) {
  const r = await fetch(url);
  if (!r.ok) {
    const why = (await r.text()).trim();
    throw new Error(`cannot load ${url}: ${r.status} ${r.statusText}${why ? ': ' + why : ''}`);
  }
  const total = Number(r.headers.get('Content-Length')) || 0;
  const reader = r.body.getReader();
  const parts = [];
  let got = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    parts.push(value);
    got += value.length;
    onProgress(got, total);
  }
  if (total && got !== total) throw new Error(`cannot load ${url}: got ${got} of ${total} bytes`);
  const buf = new Uint8Array(got);
  let o = 0;
  for (const p of parts) { buf.set(p, o); o += p.length; }
  return buf.buffer;
}

// ------------------------------------------------------------------ state
const state = {
  renderer: null,
  scene: null,       // scene.json
  views: [],         // {path, scene, gpu, cut, stats}
  cam: null,         // {eye, target, up, fov}
  mode: 'orbit',
  startCam: null,    // the URL's camera (voxdag view --camera-file), else null
  lod: 0,            // pixels (render --lod); 0: every voxel exactly
  frameMs: 0,
};

// A camera file's object (schemas/render-outputs.md), checked as render's
// vd_camera_check does; throws with the field that is wrong.
function cameraFromFile(o) {
  const vec = (k, dflt) => {
    const v = o[k] === undefined ? dflt : o[k];
    if (!Array.isArray(v) || v.length !== 3 || !v.every(Number.isFinite)) throw new Error(`camera: "${k}" is not 3 numbers`);
    return v.slice();
  };
  if (o === null || typeof o !== 'object') throw new Error('camera: not a JSON object');
  const c = { eye: vec('eye'), target: vec('target'), up: vec('up', [0, 1, 0]), fov: o.fov === undefined ? 40 : o.fov };
  if (!(Number.isFinite(c.fov) && c.fov > 0 && c.fov < 180)) throw new Error('camera: "fov" is not in (0, 180) degrees');
  const f = sub(c.target, c.eye);
  if (!(dot(f, f) > 0)) throw new Error('camera: "eye" equals "target"');
  const x = cross(norm(f), c.up);
  if (!(dot(x, x) > 1e-12)) throw new Error('camera: "up" is parallel to the view');
  return c;
}

function defaultCamera(s) {
  // render's "front" preset: looking along -Z, framing the bounding box
  const h = s.header;
  const centre = [0, 1, 2].map((a) => 0.5 * (h.bboxMin[a] + h.bboxMax[a]));
  const ext = [0, 1, 2].map((a) => h.bboxMax[a] - h.bboxMin[a]);
  const dist = 1.08 * (0.5 * ext[2] + (0.5 * Math.max(ext[0], ext[1])) / Math.tan((40 * Math.PI) / 360));
  return { eye: add(centre, [0, 0, dist]), target: centre, up: [0, 1, 0], fov: 40 };
}

// The colour sources scene.json lists: colorize's files (colours.*) and
// voxelize's directories of colour chunks (*.col).
function colourSources(files) {
  const out = new Set();
  for (const f of files) {
    if (/(^|\/)colours\.[a-z0-9]+$/.test(f.path)) out.add(f.path);
    else if (/\.col$/.test(f.path)) out.add(f.path.replace(/\/[^/]+$/, ''));
  }
  return [...out];
}

// The colour array of `path` as the server decodes it with the library
// (every method the library reads), checked against the scene.
async function loadColours(path, scene) {
  // the shader's per-node counts are u32 words (formats.js saturates
  // them): geometry of any size, colours of at most 2^32 - 1 voxels
  if (scene.voxels > 0xffffffff)
    throw new Error(`colours of ${scene.voxels} voxels: this viewer looks colours up through 32-bit counts (at most 4294967295 voxels)`);
  const r = await fetch('colours/' + path);
  if (!r.ok) {
    const why = (await r.text()).trim();
    throw new Error(`cannot load colours ${path}: ${r.status} ${r.statusText}${why ? ': ' + why : ''}`);
  }
  const levels = Number(r.headers.get('X-Voxdag-Levels'));
  const rgb = new Uint8Array(await r.arrayBuffer());
  if (levels !== scene.header.levels)
    throw new Error(`colours ${path} were made at depth ${levels}, the scene has depth ${scene.header.levels}`);
  if (rgb.length !== 3 * scene.voxels)
    throw new Error(`colours ${path} cover ${rgb.length / 3} voxels, the scene has ${scene.voxels}`);
  return state.renderer.uploadColours(rgb, path);
}

async function loadView(path, coloursPath) {
  const fmt = formatOf(path);
  if (!fmt) throw new Error(`${path}: not an encoding this viewer reads (.ssvdag, .ssvdag48, .esvdag, .svdag, .ussvdag)`);
  const t0 = performance.now();
  const buf = await fetchWithProgress('data/' + path, (got, total) =>
    status(`loading ${path}: ${(got / 2 ** 20).toFixed(1)}${total ? ' of ' + (total / 2 ** 20).toFixed(1) : ''} MB`));
  const scene = decoders[fmt](buf, path);
  const gpu = state.renderer.upload(scene);
  const colours = coloursPath ? await loadColours(coloursPath, scene) : null;
  return { path, scene, gpu, colours, coloursPath: colours ? coloursPath : '', cut: scene.header.levels, loadMs: performance.now() - t0,
    voxels: scene.voxels, bytes: buf.byteLength, table: await lowerResolutions(path) };
}

// encode's Table 2 beside the encoding (DIR/*.tables.json): the numbers
// of each lower resolution, which the slider shows (the DAG cut there and
// reduced again, as the report counts it). Optional: null without it.
async function lowerResolutions(path) {
  const dir = path.replace(/[^/]+$/, '');
  const f = state.scene.files.find((x) => x.path.startsWith(dir) && !x.path.slice(dir.length).includes('/') &&
    x.path.endsWith('.tables.json'));
  if (!f) return null;
  try {
    return (await (await fetch('data/' + f.path)).json()).table2 || null;
  } catch (e) {
    return null;
  }
}

function statsText(v) {
  const h = v.scene.header, f = v.scene.format;
  const loaded = `loaded in ${v.loadMs.toFixed(0)} ms`;
  if (v.cut < h.levels) {
    // what is shown: the scene at 2^cut, from encode's table
    const row = v.table && v.table.find((r) => r.levels === v.cut);
    const nodes = row && row[`nodes_${f === 'esvdag' ? 'svdag' : f === 'ussvdag' ? 'ssvdag' : f}`];
    if (row && nodes !== undefined && row[`bytes_${f}`] !== undefined)
      return `${v.path} at 2^${v.cut} (of 2^${h.levels}): ${nodes} nodes, ` +
        `${(row[`bytes_${f}`] / 2 ** 20).toFixed(3)} MB, ${row[`bits_per_voxel_${f}`].toFixed(3)} bits/voxel, ` +
        `${row.voxels} voxels (encode's table); ${loaded}`;
    return `${v.path}: 2^${h.levels} shown at 2^${v.cut} (no table of 2^${v.cut}: the full scene's numbers) ` +
      `${h.nodeCount} nodes, ${(v.scene.countedBytes / 2 ** 20).toFixed(3)} MB; ${loaded}`;
  }
  const bpv = v.voxels ? ((8 * v.scene.countedBytes) / v.voxels).toFixed(3) : '?';
  return `${v.path}: 2^${h.levels}, ${h.nodeCount} nodes, ${(v.scene.countedBytes / 2 ** 20).toFixed(3)} MB, ` +
    `${bpv} bits/voxel, ${v.voxels} voxels; ${loaded}`;
}

function draw() {
  const r = state.renderer;
  if (!r || !state.views.length) return;
  const canvas = $('view');
  const n = state.views.length;
  const w = Math.floor(canvas.width / n), h = canvas.height;
  const t0 = performance.now();
  // the red differences are exact (as render --diff refuses --lod): so is
  // the picture under them
  r.lod = state.views.length === 2 && $('diff').checked ? 0 : state.lod;
  state.views.forEach((v, i) => r.draw(v, state.cam, i * w, 0, w, h));
  const px = new Uint8Array(4);
  r.gl.readPixels(0, 0, 1, 1, r.gl.RGBA, r.gl.UNSIGNED_BYTE, px); // wait for the GPU
  state.frameMs = performance.now() - t0;
  const diff = markDifferences(w, h);
  $('stats').textContent = state.views.map(statsText).join('\n') +
    `\nframe: ${state.frameMs.toFixed(1)} ms for ${canvas.width}x${canvas.height}` +
    (diff === null ? '' : `\n${diff} pixels show a voxel set in only one of the two scenes (red)`);
}

// Two scenes side by side (lossless and lossy or edited): the pixels whose
// hit cells differ, red on an overlay over both views, as render --diff
// marks the voxels set in one scene only. Returns their count, or null
// with one scene or the box unticked.
function markDifferences(w, h) {
  const overlay = $('overlay'), canvas = $('view');
  overlay.width = canvas.width;
  overlay.height = canvas.height;
  const g = overlay.getContext('2d');
  g.clearRect(0, 0, overlay.width, overlay.height);
  state.diffPixels = null;
  if (state.views.length !== 2 || !$('diff').checked) return null;
  const [a, b] = state.views.map((v) => state.renderer.readBack(v, state.cam, w, h).ids);
  const img = g.createImageData(w, h);
  let n = 0;
  for (let i = 0; i < w * h; i++) {
    let same = true;
    for (let k = 0; k < 4; k++) same = same && a[4 * i + k] === b[4 * i + k];
    if (same) continue;
    n++;
    img.data.set([230, 13, 10, 255], 4 * i);
  }
  g.putImageData(img, 0, 0);
  g.putImageData(img, w, 0);
  state.diffPixels = n;
  return n;
}

let pending = false;
function redraw() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => { pending = false; draw(); });
}

// ---------------------------------------------------------------- cameras
function orbit(dx, dy) {
  const c = state.cam;
  const f = frame(c);
  let off = sub(c.eye, c.target);
  const dist = Math.sqrt(dot(off, off));
  const rotate = (v, axis, ang) => { // Rodrigues
    const k = norm(axis), cs = Math.cos(ang), sn = Math.sin(ang);
    return add(add(scale(v, cs), scale(cross(k, v), sn)), scale(k, dot(k, v) * (1 - cs)));
  };
  off = rotate(off, c.up, -dx * 0.01);
  off = rotate(off, f.right, -dy * 0.01);
  off = scale(norm(off), dist);
  if (Math.abs(dot(norm(off), norm(c.up))) < 0.995) c.eye = add(c.target, off);
}

function fly(dx, dy) {
  const c = state.cam;
  const f = frame(c);
  const dist = Math.sqrt(dot(sub(c.target, c.eye), sub(c.target, c.eye)));
  let d = norm(add(add(f.fwd, scale(f.right, dx * 0.005)), scale(f.up, -dy * 0.005)));
  if (Math.abs(dot(d, norm(c.up))) < 0.995) c.target = add(c.eye, scale(d, dist));
}

function setupInput(canvas) {
  let drag = null;
  canvas.addEventListener('pointerdown', (e) => { drag = [e.clientX, e.clientY]; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener('pointerup', () => { drag = null; });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag || !state.cam) return;
    const dx = e.clientX - drag[0], dy = e.clientY - drag[1];
    drag = [e.clientX, e.clientY];
    (state.mode === 'orbit' ? orbit : fly)(dx, dy);
    redraw();
  });
  canvas.addEventListener('wheel', (e) => {
    if (!state.cam) return;
    e.preventDefault();
    const c = state.cam;
    const k = Math.exp(e.deltaY * 0.001);
    if (state.mode === 'orbit') c.eye = add(c.target, scale(sub(c.eye, c.target), k));
    else { const step = scale(sub(c.target, c.eye), (1 - k)); c.eye = add(c.eye, step); c.target = add(c.target, step); }
    redraw();
  }, { passive: false });
  window.addEventListener('keydown', (e) => {
    if (state.mode !== 'fly' || !state.cam) return;
    const c = state.cam;
    const f = frame(c);
    const speed = 8 * state.views[0].scene.voxelSize * (e.shiftKey ? 8 : 1);
    const moves = { w: f.fwd, s: scale(f.fwd, -1), d: f.right, a: scale(f.right, -1), e: f.up, q: scale(f.up, -1) };
    const m = moves[e.key.toLowerCase()];
    if (!m) return;
    c.eye = add(c.eye, scale(m, speed));
    c.target = add(c.target, scale(m, speed));
    redraw();
  });
}

// ------------------------------------------------------------------- main
async function showViews(paths, coloursPath) {
  state.views.forEach((v) => {
    state.renderer.gl.deleteTexture(v.gpu.tex);
    if (v.colours) state.renderer.gl.deleteTexture(v.colours.tex);
  });
  state.views = [];
  for (const p of paths) state.views.push(await loadView(p, coloursPath));
  const first = state.views[0];
  if (!state.cam) state.cam = state.startCam ? { ...state.startCam } : defaultCamera(first.scene);
  const slider = $('cut');
  slider.max = first.scene.header.levels;
  slider.value = first.cut;
  $('cutLabel').textContent = `2^${first.cut}`;
  status(`showing ${paths.join(', ')}`);
  draw();
}

async function main() {
  const canvas = $('view');
  const params = new URLSearchParams(location.search);
  if (params.get('camera')) {
    // voxdag view --camera-file: a camera file's JSON, image size included
    let o;
    try { o = JSON.parse(params.get('camera')); } catch (e) { throw new Error(`camera: not JSON (${e.message})`); }
    state.startCam = cameraFromFile(o);
    if (Number.isInteger(o.width) && Number.isInteger(o.height) && o.width > 0 && o.height > 0) {
      canvas.width = Math.min(o.width, 16384);
      canvas.height = Math.min(o.height, 16384);
    }
  }
  if (params.get('lod') !== null) {
    state.lod = Number(params.get('lod'));
    if (!(Number.isFinite(state.lod) && state.lod >= 0)) throw new Error(`lod '${params.get('lod')}' is not a number of pixels >= 0`);
  }
  const lodPick = $('lod');
  if (![...lodPick.options].some((o) => Number(o.value) === state.lod)) lodPick.add(new Option(`${state.lod} px`, String(state.lod)));
  lodPick.value = String(state.lod);
  lodPick.onchange = () => { state.lod = Number(lodPick.value); redraw(); };
  if (params.get('size')) {
    const [w, h] = params.get('size').split('x').map(Number);
    canvas.width = w;
    canvas.height = h;
  }
  state.renderer = new Renderer(canvas);
  const r = await fetch('scene.json');
  if (!r.ok) throw new Error(`cannot load scene.json: ${r.status}`);
  state.scene = await r.json();
  document.title = `voxdag view: ${state.scene.name}`;
  $('title').textContent = state.scene.name;
  const encodings = state.scene.files.filter((f) => formatOf(f.path)).map((f) => f.path);
  if (!encodings.length) throw new Error('the output directory has no encoding this viewer reads (.ssvdag, .ssvdag48, .esvdag, .svdag, .ussvdag) yet: run the pipeline first');
  // .ssvdag first: the smallest the pipeline writes
  encodings.sort((a, b) => (b.endsWith('.ssvdag') - a.endsWith('.ssvdag')) || a.localeCompare(b));
  const pick = $('file'), pick2 = $('file2');
  for (const e of encodings) {
    pick.add(new Option(e, e));
    pick2.add(new Option(e, e));
  }
  pick2.add(new Option('(none)', ''), 0);
  pick2.value = '';
  const pickC = $('colours');
  pickC.add(new Option('(grey)', ''));
  const sources = colourSources(state.scene.files);
  for (const c of sources) pickC.add(new Option(c, c));
  // the URL's colours (colours= for grey), else the pipeline's own:
  // colorize's compressed file first (auto, the pipelines' method), then
  // any colorize file, then voxelize's chunks
  const colourDefault = params.get('colours') === null;
  if (!colourDefault) {
    if (params.get('colours') && ![...pickC.options].some((o) => o.value === params.get('colours')))
      pickC.add(new Option(params.get('colours'), params.get('colours')));
    pickC.value = params.get('colours');
  } else {
    pickC.value = sources.find((c) => /colours\.auto$/.test(c)) || sources.find((c) => /colours\./.test(c)) || sources[0] || '';
  }
  const chosen = () => [pick.value, pick2.value].filter(Boolean);
  const wanted = params.get('file');
  if (wanted) pick.value = wanted;
  if (params.get('file2')) pick2.value = params.get('file2');
  if (params.get('diff')) $('diff').checked = true;
  const reload = () => showViews(chosen(), pickC.value).catch(showError);
  pick.onchange = reload;
  pick2.onchange = reload;
  pickC.onchange = reload;
  $('cut').oninput = () => {
    const c = Number($('cut').value);
    state.views.forEach((v) => { v.cut = c; });
    $('cutLabel').textContent = `2^${c}`;
    redraw();
  };
  $('mode').onchange = () => { state.mode = $('mode').value; };
  $('diff').onchange = redraw;
  $('shot').onclick = () => composite().toBlob((b) => {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(b);
    a.download = `${state.scene.name}.png`;
    a.click();
  });
  $('reset').onclick = () => { state.cam = state.startCam ? { ...state.startCam } : defaultCamera(state.views[0].scene); redraw(); };
  // the camera as a file render --camera-file reads: same picture, on the CPU
  $('camfile').onclick = () => {
    const c = state.cam;
    const text = JSON.stringify({ eye: c.eye, target: c.target, up: c.up, fov: c.fov, width: canvas.width, height: canvas.height }) + '\n';
    const a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([text], { type: 'application/json' }));
    a.download = `${state.scene.name}.camera.json`;
    a.click();
  };
  setupInput(canvas);
  const first = wanted && !encodings.includes(wanted) ? [wanted] : chosen();
  try {
    await showViews(first, pickC.value);
  } catch (e) {
    // colours chosen here, not asked for, that cannot be shown (another
    // voxel set, more than the GPU holds): the geometry in grey, and why
    if (!colourDefault || !pickC.value) throw e;
    pickC.value = '';
    await showViews(first, '');
    status(`showing ${first.join(', ')} in grey: ${e.message}`);
  }
}

// The view with the difference overlay on top, for the screenshot.
function composite() {
  const c = document.createElement('canvas');
  c.width = $('view').width;
  c.height = $('view').height;
  const g = c.getContext('2d');
  g.drawImage($('view'), 0, 0);
  g.drawImage($('overlay'), 0, 0);
  return c;
}

function showError(e) {
  status(e instanceof FormatError ? `cannot read ${e.message}` : e.message, true);
  state.error = e.message;
}

// The tests' interface.
window.voxdag = {
  ready: null,
  error: () => state.error || null,
  stats: () => ({ frameMs: state.frameMs, diffPixels: state.diffPixels, views: state.views.map((v) => ({ path: v.path, colours: v.coloursPath, loadMs: v.loadMs, nodes: v.scene.header.nodeCount })) }),
  // cam: a camera file's object {eye, target, up, fov, width, height}
  readBack(cam, viewIndex = 0) {
    const c = { eye: cam.eye, target: cam.target, up: cam.up || [0, 1, 0], fov: cam.fov || 40 };
    state.renderer.lod = state.lod;
    const r = state.renderer.readBack(state.views[viewIndex], c, cam.width, cam.height);
    return { ids: Array.from(r.ids), depth: Array.from(r.depth, (x) => (Number.isFinite(x) ? x : null)), ms: r.ms };
  },
  // The voxels' own colours (no shading) of view 0 for cam, RGB rows from
  // the top, drawn into the canvas (sized by the URL's size=WxH).
  colourImage(cam) {
    const r = state.renderer, gl = r.gl;
    const c = { eye: cam.eye, target: cam.target, up: cam.up || [0, 1, 0], fov: cam.fov || 40 };
    r.shade = false;
    r.lod = state.lod;
    r.draw(state.views[0], c, 0, 0, cam.width, cam.height);
    r.shade = true;
    const px = new Uint8Array(4 * cam.width * cam.height);
    gl.readPixels(0, 0, cam.width, cam.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const out = [];
    for (let y = cam.height - 1; y >= 0; y--)
      for (let x = 0; x < cam.width; x++) out.push(px[4 * (y * cam.width + x)], px[4 * (y * cam.width + x) + 1], px[4 * (y * cam.width + x) + 2]);
    return out;
  },
  camera: () => state.cam,
  // what the screenshot button saves, as a data: URL
  screenshot: () => composite().toDataURL('image/png'),
  setCamera(cam) {
    state.cam = { eye: cam.eye, target: cam.target, up: cam.up || [0, 1, 0], fov: cam.fov || 40 };
    draw();
    return state.frameMs;
  },
};
window.voxdag.ready = main().then(() => 'ok', (e) => { showError(e); return 'error'; });
