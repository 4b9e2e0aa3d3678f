// vps viewer: dependency-free WebGL2 (2D-canvas fallback). Served by crates/vps-view; no build step.
//
// Data: /scene (JSON metadata), /scene/boxes and /scene/shell (little-endian f32 xyz, metres),
// /scene/mesh, /scene/part_mesh and /scene/swept_mesh (f32 triangle corners, 9 per triangle: the
// static meshes in the world frame, the part's mesh in its body frame, a study's swept volume in
// the world frame), /state (latest state, JSON) and /ws (the same states pushed at 30 Hz). World
// frame: z up, metres. With window.VPS_EMBEDDED set (a standalone page, e.g. a study's report),
// the same data comes from the page itself and nothing is fetched.
'use strict';
(function () {
  const $ = (id) => document.getElementById(id);
  // {state, scene, files: {route: base64}} when the page carries its own data; null when served.
  const EMBEDDED = window.VPS_EMBEDDED || null;
  const canvas = $('view');
  const HISTORY = 300; // chart samples (10 s at the default 30 states a second; ?fps=N applies N a second)
  const FORCE_SCALE = 0.05; // m of arrow per N
  const TORQUE_SCALE = 10.0; // m of arrow per N·m
  const FETCH_PATIENCE_MS = 30000; // longest wait for a request's answer (headers) before asking again
  const FETCH_TRIES = 5; // requests of one scene file (a second apart) before the page reports an error

  // Page options from the query string: ?renderer=2d forces the 2D-canvas fallback; ?fps=N caps
  // the redraw rate and the rate states are applied to the panel and charts (default 30).
  const params = new URLSearchParams(location.search);
  const MAX_FPS = Math.max(0.2, Number(params.get('fps')) || 30);

  let scene = null; // metadata
  let boxes = new Float32Array(0); // world xyz of the scene's boxes
  let shell = new Float32Array(0); // body-frame xyz of the part's drawn points
  let mesh = null; // static meshes: {pos, nrm, count} (world frame), null without
  let partMesh = null; // the part's mesh (body frame), null without
  let sweptMesh = null; // a study's swept volume (world frame), null without
  let otherMeshes = []; // the other moving parts' meshes (each in its own grip frame), in order
  let showSwept = true;
  let study = null; // a study's track (scene.study), null without
  let studyIndex = 0; // the study frame shown while no live frame is
  let showVoxels = true; // the Surface voxel boxes (and the shell points): an overlay with meshes
  let state = null; // latest state message
  let renderer = null;
  let lastMessageAt = 0;
  const camera = { yaw: -0.9, pitch: 0.45, dist: 0.6, target: [0, 0, 0], follow: true };

  // ---- small vector and matrix helpers (column-major 4x4, like GL) ----
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const len = (a) => Math.sqrt(dot(a, a));
  const norm = (a) => { const l = len(a) || 1; return scale(a, 1 / l); };

  function perspective(fovy, aspect, near, far) {
    const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
  }
  function lookAt(eye, target, up) {
    const z = norm(sub(eye, target)), x = norm(cross(up, z)), y = cross(z, x);
    return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
      -dot(x, eye), -dot(y, eye), -dot(z, eye), 1];
  }
  function mul(a, b) {
    const o = new Array(16).fill(0);
    for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
      o[c * 4 + r] = s;
    }
    return o;
  }
  // Rotation + translation from a quaternion [x, y, z, w] and a position.
  function poseMatrix(q, t) {
    const [x, y, z, w] = q;
    return [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0,
      2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0,
      2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0,
      t[0], t[1], t[2], 1];
  }
  const IDENTITY = poseMatrix([0, 0, 0, 1], [0, 0, 0]);
  function transform(m, p) {
    return [m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
      m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
      m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14]];
  }
  function project(m, p) { // clip-space projection → [x, y, w]
    return [m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
      m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
      m[3] * p[0] + m[7] * p[1] + m[11] * p[2] + m[15]];
  }

  // ---- what to draw this frame, shared by both renderers ----
  const OVERLAY_COLOR = [0.95, 0.6, 0.2]; // Surface voxel boxes over meshes
  const PART_COLOR = [0.92, 0.9, 0.86];
  const OTHER_PART_COLOR = [0.95, 0.74, 0.33]; // the other moving parts of a scene of several
  // Where the other parts are drawn: the frame's poses, else where they start.
  const otherPoses = (f) => (scene.other_parts || []).map((p, k) => (f && f.others && f.others[k]) || p.start);
  const PATH_COLOR = [0.35, 0.63, 1]; // the simulated hand's path
  const STUDY_PATH_COLOR = [0.3, 0.85, 0.45]; // a study's grip path
  const CLOSEST_COLOR = [1, 0.25, 0.25]; // a study's closest approach
  const SWEPT_COLOR = [0.3, 0.8, 0.5]; // a study's swept volume (translucent)
  function depthColor(depth) {
    const t = Math.min(1, depth / (scene ? scene.voxel_size_m : 0.005));
    return [1, 0.88 * (1 - t), 0.25 * (1 - t)];
  }
  function heightColor(z) {
    const lo = scene.bounds_min_m[2], hi = scene.bounds_max_m[2];
    const t = Math.max(0, Math.min(1, (z - lo) / ((hi - lo) || 1)));
    return [0.35 + 0.25 * t, 0.45 + 0.2 * t, 0.55 - 0.15 * t];
  }
  // The force and torque sent to each part's device, drawn from the part's grip: the first
  // part's, then every other part's.
  function arrows(f) {
    const pair = (c, force, torque) => [
      { from: c, to: add(c, scale(force, FORCE_SCALE)), color: [0.25, 1, 0.38] },
      { from: c, to: add(c, scale(torque, TORQUE_SCALE)), color: [1, 0.56, 0.19] },
    ];
    return [
      ...pair(f.part.position_m, f.force_n, f.torque_nm),
      ...(f.others || []).flatMap((o) => pair(o.position_m, o.force_n, o.torque_nm)),
    ];
  }
  const GHOST_COLOR = [0.35, 0.63, 1]; // a hand's pose (the part is coupled to it)
  // The other parts' handles (their ghosts) in this frame, each with its part's index.
  const otherHandles = (f) => ((f && f.others) || []).map((o, k) => [o.handle, k]).filter(([h]) => h);
  // The part's pose as drawn: the live frame's, else the study's frame being shown, else null.
  function shownPart() {
    const f = state && state.frame;
    if (f) return f.part;
    if (study) return { position_m: study.position_m[studyIndex], orientation_xyzw: study.orientation_xyzw[studyIndex] };
    return null;
  }
  function updateCamera() {
    const p = shownPart();
    if (camera.follow && p) camera.target = p.position_m.slice();
  }
  const FOV = 0.9; // vertical field of view (rad)
  function cameraEye() {
    const cp = Math.cos(camera.pitch);
    return add(camera.target, scale([cp * Math.cos(camera.yaw), cp * Math.sin(camera.yaw), Math.sin(camera.pitch)], camera.dist));
  }
  function viewProjection(width, height) {
    updateCamera();
    const eye = cameraEye();
    const diag = scene ? len(sub(scene.bounds_max_m, scene.bounds_min_m)) : 1;
    // Following the part through a cluttered scene, the near plane cuts away what lies between the
    // eye and the part (walls behind the camera would hide it); the whole-scene view keeps it all.
    const near = camera.follow ? camera.dist * 0.6 : Math.max(1e-4, camera.dist * 0.02);
    const far = camera.dist * 4 + diag * 2;
    return mul(perspective(FOV, width / Math.max(1, height), near, far), lookAt(eye, camera.target, [0, 0, 1]));
  }

  // Triangle soup (9 floats per triangle) with one normal per face, repeated at its 3 corners.
  function withNormals(pos) {
    const nrm = new Float32Array(pos.length);
    for (let i = 0; i < pos.length; i += 9) {
      const a = [pos[i], pos[i + 1], pos[i + 2]];
      const n = norm(cross(sub([pos[i + 3], pos[i + 4], pos[i + 5]], a), sub([pos[i + 6], pos[i + 7], pos[i + 8]], a)));
      for (let k = 0; k < 9; k += 3) nrm.set(n, i + k);
    }
    return { pos, nrm, count: pos.length / 3 };
  }

  // ---- level of detail: the scene's boxes sorted into cubic chunks; chunks near the eye are drawn
  // as boxes, the rest as point sprites (one vertex instead of 36) ----
  const CHUNK = 0.2; // m
  let chunks = []; // {first, count, centre, radius}, in box order
  function buildChunks() {
    const n = boxes.length / 3, lo = scene.bounds_min_m;
    const key = new Array(n), dims = [0, 1, 2].map((a) => Math.ceil((scene.bounds_max_m[a] - lo[a]) / CHUNK) + 1);
    for (let i = 0; i < n; i++) {
      const c = [0, 1, 2].map((a) => Math.max(0, Math.floor((boxes[3 * i + a] - lo[a]) / CHUNK)));
      key[i] = (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    }
    const order = Array.from({ length: n }, (_, i) => i).sort((a, b) => key[a] - key[b]);
    const sorted = new Float32Array(boxes.length);
    order.forEach((from, to) => sorted.set(boxes.subarray(3 * from, 3 * from + 3), 3 * to));
    boxes = sorted;
    chunks = [];
    for (let i = 0; i < n;) {
      let j = i;
      while (j < n && key[order[j]] === key[order[i]]) j++;
      const k = key[order[i]], c = [k % dims[0], Math.floor(k / dims[0]) % dims[1], Math.floor(k / (dims[0] * dims[1]))];
      chunks.push({ first: i, count: j - i, centre: c.map((v, a) => lo[a] + (v + 0.5) * CHUNK), radius: CHUNK * 0.87 + scene.box_size_m });
      i = j;
    }
  }
  // Consecutive chunks of the same level merged into ranges.
  function lodRanges(eye) {
    const nearLimit = Math.max(0.3, camera.dist * 1.2), ranges = [];
    for (const c of chunks) {
      const near = len(sub(c.centre, eye)) - c.radius < nearLimit;
      const last = ranges[ranges.length - 1];
      if (last && last.near === near && last.first + last.count === c.first) last.count += c.count;
      else ranges.push({ first: c.first, count: c.count, near });
    }
    return ranges;
  }

  // ---- WebGL2 renderer: instanced boxes and lines ----
  const BOX_VS = `#version 300 es
  in vec3 a_corner; in vec3 a_normal; in vec3 a_offset; in vec3 a_color;
  uniform mat4 u_viewProj; uniform mat4 u_model; uniform float u_size; uniform vec3 u_heightLo; uniform float u_heightSpan; uniform bool u_tint;
  out vec3 v_color; out float v_light;
  void main() {
    vec3 c = (u_model * vec4(a_offset, 1.0)).xyz;
    gl_Position = u_viewProj * vec4(c + a_corner * u_size, 1.0);
    float t = clamp((c.z - u_heightLo.z) / u_heightSpan, 0.0, 1.0);
    v_color = u_tint ? vec3(0.35 + 0.25 * t, 0.45 + 0.2 * t, 0.55 - 0.15 * t) : a_color;
    v_light = 0.45 + 0.55 * max(dot(a_normal, normalize(vec3(0.35, 0.25, 0.9))), 0.0) + 0.15 * abs(a_normal.x);
  }`;
  const BOX_FS = `#version 300 es
  precision mediump float; in vec3 v_color; in float v_light; uniform float u_alpha; out vec4 o;
  void main() { o = vec4(v_color * v_light, u_alpha); }`;
  // Far boxes are drawn as one point sprite each (a square of the box's projected size).
  const POINT_VS = `#version 300 es
  in vec3 a_offset;
  uniform mat4 u_viewProj; uniform float u_size; uniform float u_pixelScale; uniform vec3 u_heightLo; uniform float u_heightSpan;
  uniform bool u_tint; uniform vec3 u_color;
  out vec3 v_color;
  void main() {
    gl_Position = u_viewProj * vec4(a_offset, 1.0);
    gl_PointSize = clamp(u_size * u_pixelScale / max(gl_Position.w, 1e-4), 1.0, 64.0);
    float t = clamp((a_offset.z - u_heightLo.z) / u_heightSpan, 0.0, 1.0);
    v_color = (u_tint ? vec3(0.35 + 0.25 * t, 0.45 + 0.2 * t, 0.55 - 0.15 * t) : u_color) * 0.85;
  }`;
  const POINT_FS = `#version 300 es
  precision mediump float; in vec3 v_color; out vec4 o;
  void main() { vec2 d = abs(gl_PointCoord - 0.5); o = vec4(v_color * (max(d.x, d.y) > 0.42 ? 0.7 : 1.0), 1.0); }`;
  // Meshes: per-face normals, lit two-sided (abs) by a headlight and a fixed sun.
  const MESH_VS = `#version 300 es
  in vec3 a_pos; in vec3 a_normal;
  uniform mat4 u_viewProj; uniform mat4 u_model; uniform vec3 u_heightLo; uniform float u_heightSpan; uniform bool u_tint; uniform vec3 u_color;
  out vec3 v_color; out vec3 v_normal; out vec3 v_world;
  void main() {
    vec4 w = u_model * vec4(a_pos, 1.0);
    v_world = w.xyz; v_normal = mat3(u_model) * a_normal;
    gl_Position = u_viewProj * w;
    float t = clamp((w.z - u_heightLo.z) / u_heightSpan, 0.0, 1.0);
    v_color = u_tint ? vec3(0.5 + 0.3 * t, 0.55 + 0.2 * t, 0.62 - 0.12 * t) : u_color;
  }`;
  const MESH_FS = `#version 300 es
  precision mediump float; in vec3 v_color; in vec3 v_normal; in vec3 v_world;
  uniform vec3 u_eye; uniform float u_alpha; out vec4 o;
  void main() {
    vec3 n = normalize(v_normal);
    float head = abs(dot(n, normalize(u_eye - v_world)));
    float sun = abs(dot(n, normalize(vec3(0.35, 0.25, 0.9))));
    o = vec4(v_color * (0.18 + 0.62 * head + 0.3 * sun), u_alpha);
  }`;
  const LINE_VS = `#version 300 es
  in vec3 a_pos; uniform mat4 u_viewProj; void main() { gl_Position = u_viewProj * vec4(a_pos, 1.0); }`;
  const LINE_FS = `#version 300 es
  precision mediump float; uniform vec3 u_color; out vec4 o; void main() { o = vec4(u_color, 1.0); }`;

  function cubeGeometry() {
    const faces = [[[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[-1, 0, 0], [0, 0, 1], [0, 1, 0]],
      [[0, 1, 0], [0, 0, 1], [1, 0, 0]], [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
      [[0, 0, 1], [1, 0, 0], [0, 1, 0]], [[0, 0, -1], [0, 1, 0], [1, 0, 0]]];
    const pos = [], nrm = [];
    for (const [n, u, v] of faces) {
      const corner = (a, b) => [0, 1, 2].map((i) => 0.5 * n[i] + a * 0.5 * u[i] + b * 0.5 * v[i]);
      for (const [a, b] of [[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]]) {
        pos.push(...corner(a, b)); nrm.push(...n);
      }
    }
    return { pos: new Float32Array(pos), nrm: new Float32Array(nrm), count: 36 };
  }

  function makeGL() {
    if (params.get('renderer') === '2d') return null;
    let gl = null;
    try { gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true }); } catch (e) { gl = null; }
    if (!gl) return null;
    const program = (vs, fs) => {
      const p = gl.createProgram();
      for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
        const s = gl.createShader(type);
        gl.shaderSource(s, src); gl.compileShader(s);
        if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
        gl.attachShader(p, s);
      }
      gl.linkProgram(p);
      if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
      return p;
    };
    let boxProg, lineProg, pointProg, meshProg;
    try {
      boxProg = program(BOX_VS, BOX_FS); lineProg = program(LINE_VS, LINE_FS); pointProg = program(POINT_VS, POINT_FS);
      meshProg = program(MESH_VS, MESH_FS);
    } catch (e) {
      console.warn('WebGL2 shaders failed, using the 2D canvas:', e); return null;
    }
    const loc = (p, n) => gl.getUniformLocation(p, n);
    const attr = (p, n) => gl.getAttribLocation(p, n);
    const cube = cubeGeometry();
    const buffer = (data, usage) => { const b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, usage || gl.STATIC_DRAW); return b; };
    const cubePos = buffer(cube.pos), cubeNrm = buffer(cube.nrm);
    const sceneBuf = buffer(boxes), shellBuf = buffer(shell);
    const meshBufs = {}; // name → {pos, nrm, count}
    const contactBuf = gl.createBuffer(), contactColorBuf = gl.createBuffer(), lineBuf = gl.createBuffer();
    const A = { corner: attr(boxProg, 'a_corner'), normal: attr(boxProg, 'a_normal'), offset: attr(boxProg, 'a_offset'), color: attr(boxProg, 'a_color') };
    const bind = (a, buf, size, divisor, first) => {
      gl.bindBuffer(gl.ARRAY_BUFFER, buf); gl.enableVertexAttribArray(a);
      gl.vertexAttribPointer(a, size, gl.FLOAT, false, 0, (first || 0) * size * 4); gl.vertexAttribDivisor(a, divisor);
    };
    // Instances first..first+count of `offsets` as boxes of edge `size` (m).
    function drawBoxes(vp, offsets, count, size, model, opts, first) {
      if (!count) return;
      gl.useProgram(boxProg);
      bind(A.corner, cubePos, 3, 0); bind(A.normal, cubeNrm, 3, 0); bind(A.offset, offsets, 3, 1, first);
      if (opts.colors) bind(A.color, opts.colors, 3, 1);
      else { gl.disableVertexAttribArray(A.color); gl.vertexAttrib3f(A.color, ...(opts.color || [1, 1, 1])); }
      gl.uniformMatrix4fv(loc(boxProg, 'u_viewProj'), false, vp);
      gl.uniformMatrix4fv(loc(boxProg, 'u_model'), false, model);
      gl.uniform1f(loc(boxProg, 'u_size'), size);
      gl.uniform1f(loc(boxProg, 'u_alpha'), opts.alpha || 1);
      gl.uniform1i(loc(boxProg, 'u_tint'), opts.tint ? 1 : 0);
      gl.uniform3fv(loc(boxProg, 'u_heightLo'), scene.bounds_min_m);
      gl.uniform1f(loc(boxProg, 'u_heightSpan'), (scene.bounds_max_m[2] - scene.bounds_min_m[2]) || 1);
      gl.drawArraysInstanced(gl.TRIANGLES, 0, cube.count, count);
      gl.vertexAttribDivisor(A.offset, 0);
      if (opts.colors) gl.vertexAttribDivisor(A.color, 0);
    }
    // A mesh uploaded by setScene, at `model`: height-tinted (`opts.tint`) or in `opts.color`.
    function drawMesh(vp, name, model, opts) {
      const m = meshBufs[name];
      if (!m || !m.count) return;
      gl.useProgram(meshProg);
      bind(attr(meshProg, 'a_pos'), m.pos, 3, 0); bind(attr(meshProg, 'a_normal'), m.nrm, 3, 0);
      gl.uniformMatrix4fv(loc(meshProg, 'u_viewProj'), false, vp);
      gl.uniformMatrix4fv(loc(meshProg, 'u_model'), false, model);
      gl.uniform3fv(loc(meshProg, 'u_eye'), cameraEye());
      gl.uniform1i(loc(meshProg, 'u_tint'), opts.tint ? 1 : 0);
      gl.uniform3fv(loc(meshProg, 'u_color'), opts.color || [1, 1, 1]);
      gl.uniform1f(loc(meshProg, 'u_alpha'), opts.alpha || 1);
      gl.uniform3fv(loc(meshProg, 'u_heightLo'), scene.bounds_min_m);
      gl.uniform1f(loc(meshProg, 'u_heightSpan'), (scene.bounds_max_m[2] - scene.bounds_min_m[2]) || 1);
      gl.drawArrays(gl.TRIANGLES, 0, m.count);
    }
    // Boxes first..first+count of the scene as point sprites.
    function drawPoints(vp, first, count, pixelScale) {
      if (!count) return;
      gl.useProgram(pointProg);
      const a = attr(pointProg, 'a_offset');
      bind(a, sceneBuf, 3, 0, 0);
      gl.uniformMatrix4fv(loc(pointProg, 'u_viewProj'), false, vp);
      gl.uniform1f(loc(pointProg, 'u_size'), scene.box_size_m);
      gl.uniform1f(loc(pointProg, 'u_pixelScale'), pixelScale);
      gl.uniform3fv(loc(pointProg, 'u_heightLo'), scene.bounds_min_m);
      gl.uniform1f(loc(pointProg, 'u_heightSpan'), (scene.bounds_max_m[2] - scene.bounds_min_m[2]) || 1);
      gl.uniform1i(loc(pointProg, 'u_tint'), mesh ? 0 : 1);
      gl.uniform3fv(loc(pointProg, 'u_color'), OVERLAY_COLOR);
      gl.drawArrays(gl.POINTS, first, count);
    }
    function drawLines(vp, list) {
      gl.useProgram(lineProg);
      const a = attr(lineProg, 'a_pos');
      gl.uniformMatrix4fv(loc(lineProg, 'u_viewProj'), false, vp);
      for (const l of list) {
        gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
        gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(arrowSegments(l)), gl.DYNAMIC_DRAW);
        gl.enableVertexAttribArray(a); gl.vertexAttribPointer(a, 3, gl.FLOAT, false, 0, 0); gl.vertexAttribDivisor(a, 0);
        gl.uniform3fv(loc(lineProg, 'u_color'), l.color);
        gl.drawArrays(gl.LINES, 0, 6);
      }
    }
    // A polyline (points in the world frame) as segments; the vertices are built once per array.
    const polylineVerts = new Map();
    function drawPolyline(vp, p, color) {
      if (!p || p.length < 2) return;
      let verts = polylineVerts.get(p);
      if (!verts) {
        verts = new Float32Array((p.length - 1) * 6);
        for (let i = 0; i + 1 < p.length; i++) verts.set([...p[i], ...p[i + 1]], i * 6);
        polylineVerts.set(p, verts);
      }
      gl.useProgram(lineProg);
      const a = attr(lineProg, 'a_pos');
      gl.uniformMatrix4fv(loc(lineProg, 'u_viewProj'), false, vp);
      gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
      gl.bufferData(gl.ARRAY_BUFFER, verts, gl.DYNAMIC_DRAW);
      gl.enableVertexAttribArray(a); gl.vertexAttribPointer(a, 3, gl.FLOAT, false, 0, 0); gl.vertexAttribDivisor(a, 0);
      gl.uniform3fv(loc(lineProg, 'u_color'), color);
      gl.drawArrays(gl.LINES, 0, verts.length / 3);
    }
    let fence = null;
    return {
      mode: 'webgl2',
      busy() {
        if (!fence) return false;
        if (gl.getSyncParameter(fence, gl.SYNC_STATUS) !== gl.SIGNALED) return true;
        gl.deleteSync(fence); fence = null; return false;
      },
      draw() {
        if (fence) { gl.deleteSync(fence); fence = null; }
        drawGL();
        fence = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
        gl.flush();
      },
      setScene() {
        gl.bindBuffer(gl.ARRAY_BUFFER, sceneBuf); gl.bufferData(gl.ARRAY_BUFFER, boxes, gl.STATIC_DRAW);
        gl.bindBuffer(gl.ARRAY_BUFFER, shellBuf); gl.bufferData(gl.ARRAY_BUFFER, shell, gl.STATIC_DRAW);
        const others = otherMeshes.map((m, k) => ['other' + k, m]);
        for (const [name, m] of [['scene', mesh], ['part', partMesh], ['swept', sweptMesh], ...others]) {
          if (m) meshBufs[name] = { pos: buffer(m.pos), nrm: buffer(m.nrm), count: m.count };
        }
      },
    };
    function drawGL() {
      const w = canvas.width, h = canvas.height;
      gl.viewport(0, 0, w, h);
      gl.clearColor(0.106, 0.133, 0.169, 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      if (!scene) return;
      const vp = viewProjection(w, h);
      gl.enable(gl.DEPTH_TEST); gl.disable(gl.BLEND); gl.depthMask(true);
      const eye = cameraEye();
      drawMesh(vp, 'scene', IDENTITY, { tint: true });
      drawPolyline(vp, scene.hand_path_m, PATH_COLOR);
      if (study) {
        drawPolyline(vp, study.position_m, STUDY_PATH_COLOR);
        gl.disable(gl.DEPTH_TEST); // the closest approach is often hidden between two surfaces
        for (const l of study.closestLines) drawPolyline(vp, l, CLOSEST_COLOR);
        gl.enable(gl.DEPTH_TEST);
      }
      if (showVoxels) {
        const boxStyle = mesh ? { color: OVERLAY_COLOR } : { tint: true };
        for (const r of lodRanges(eye)) {
          if (r.near) drawBoxes(vp, sceneBuf, r.count, scene.box_size_m * 0.92, IDENTITY, boxStyle, r.first);
          else drawPoints(vp, r.first, r.count, h / (2 * Math.tan(FOV / 2)));
        }
      }
      const f = state && state.frame;
      if (!f) {
        // Before a session's first frame (or offline): the part at the study frame shown, or
        // where it starts.
        const shown = shownPart() || scene.part_start;
        if (shown) drawMesh(vp, 'part', poseMatrix(shown.orientation_xyzw, shown.position_m), { color: PART_COLOR });
        otherPoses(null).forEach((p, k) => drawMesh(vp, 'other' + k, poseMatrix(p.orientation_xyzw, p.position_m), { color: OTHER_PART_COLOR }));
        drawSwept(vp);
        return;
      }
      otherPoses(f).forEach((p, k) => drawMesh(vp, 'other' + k, poseMatrix(p.orientation_xyzw, p.position_m), { color: OTHER_PART_COLOR }));
      const pointSize = scene.shell_voxel_size_m * 0.8;
      const partPose = poseMatrix(f.part.orientation_xyzw, f.part.position_m);
      drawMesh(vp, 'part', partPose, { color: PART_COLOR });
      if (!partMesh || showVoxels) drawBoxes(vp, shellBuf, shell.length / 3, pointSize, partPose, { color: [0.91, 0.91, 0.91] });
      const contacts = contactArrays(f);
      if (contacts.count) {
        gl.bindBuffer(gl.ARRAY_BUFFER, contactBuf); gl.bufferData(gl.ARRAY_BUFFER, contacts.pos, gl.DYNAMIC_DRAW);
        gl.bindBuffer(gl.ARRAY_BUFFER, contactColorBuf); gl.bufferData(gl.ARRAY_BUFFER, contacts.col, gl.DYNAMIC_DRAW);
        drawBoxes(vp, contactBuf, contacts.count, pointSize * 1.3, IDENTITY, { colors: contactColorBuf });
      }
      gl.disable(gl.DEPTH_TEST);
      drawLines(vp, arrows(f));
      gl.enable(gl.DEPTH_TEST); gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); gl.depthMask(false);
      const handlePose = poseMatrix(f.handle.orientation_xyzw, f.handle.position_m);
      if (partMesh) drawMesh(vp, 'part', handlePose, { color: GHOST_COLOR, alpha: 0.25 });
      else drawBoxes(vp, shellBuf, shell.length / 3, pointSize, handlePose, { color: GHOST_COLOR, alpha: 0.25 });
      otherHandles(f).forEach(([h, k]) => drawMesh(vp, 'other' + k, poseMatrix(h.orientation_xyzw, h.position_m), { color: GHOST_COLOR, alpha: 0.25 }));
      gl.depthMask(true); gl.disable(gl.BLEND);
      drawSwept(vp);
    }
    // The study's swept volume, translucent, over everything opaque.
    function drawSwept(vp) {
      if (!sweptMesh || !showSwept) return;
      gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); gl.depthMask(false);
      drawMesh(vp, 'swept', IDENTITY, { color: SWEPT_COLOR, alpha: 0.22 });
      gl.depthMask(true); gl.disable(gl.BLEND);
    }
  }

  // An arrow as three segments: the shaft and two barbs.
  function arrowSegments(l) {
    const d = sub(l.to, l.from), n = len(d);
    if (n < 1e-6) return new Array(18).fill(0);
    const dir = scale(d, 1 / n), side = norm(Math.abs(dir[2]) < 0.9 ? cross(dir, [0, 0, 1]) : cross(dir, [1, 0, 0]));
    const back = sub(l.to, scale(dir, n * 0.2));
    return [...l.from, ...l.to, ...l.to, ...add(back, scale(side, n * 0.08)), ...l.to, ...sub(back, scale(side, n * 0.08))];
  }

  function contactArrays(f) {
    const n = f.contact_points.length + f.interior_points.length;
    const pos = new Float32Array(n * 3), col = new Float32Array(n * 3);
    let i = 0;
    for (const c of f.contact_points) { pos.set(c.slice(0, 3), i * 3); col.set(depthColor(c[3]), i * 3); i++; }
    for (const c of f.interior_points) { pos.set(c, i * 3); col.set([1, 0.25, 1], i * 3); i++; }
    return { pos, col, count: n };
  }

  // ---- 2D canvas fallback: mesh faces sorted far to near, projected squares for boxes and points ----
  const MAX_2D_TRIANGLES = 20000;
  function make2D() {
    const ctx = canvas.getContext('2d');
    if (!ctx) return null;
    const css = (c, a) => `rgba(${Math.round(c[0] * 255)},${Math.round(c[1] * 255)},${Math.round(c[2] * 255)},${a || 1})`;
    return {
      mode: 'canvas2d',
      draw() {
        const w = canvas.width, h = canvas.height;
        ctx.fillStyle = '#1b222b'; ctx.fillRect(0, 0, w, h);
        if (!scene) return;
        const vp = viewProjection(w, h);
        const square = (p, size, color, alpha) => {
          const q = project(vp, p);
          if (q[2] <= 1e-4) return;
          const x = (q[0] / q[2] * 0.5 + 0.5) * w, y = (0.5 - q[1] / q[2] * 0.5) * h;
          const s = Math.max(1, size / q[2] * h * 0.9);
          if (x < -s || y < -s || x > w + s || y > h + s) return;
          ctx.fillStyle = css(color, alpha); ctx.fillRect(x - s / 2, y - s / 2, s, s);
        };
        const f = state && state.frame;
        // Meshes: up to MAX_2D_TRIANGLES faces, filled far to near, shaded by their normal.
        const faces = [], eye = cameraEye();
        const addFaces = (m, model, color, cap, alpha) => {
          if (!m) return;
          const n = m.count / 3, stride = Math.max(1, Math.ceil(n / cap));
          for (let t = 0; t < n; t += stride) {
            const c = [0, 1, 2].map((k) => transform(model, [m.pos[9 * t + 3 * k], m.pos[9 * t + 3 * k + 1], m.pos[9 * t + 3 * k + 2]]));
            const q = c.map((p) => project(vp, p));
            if (q.some((v) => v[2] <= 1e-4)) continue;
            const normal = norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
            const light = 0.2 + 0.8 * Math.abs(dot(normal, norm(sub(eye, c[0]))));
            faces.push({ q, depth: q[0][2] + q[1][2] + q[2][2], color: scale(color || heightColor(c[0][2]), light), alpha });
          }
        };
        addFaces(mesh, IDENTITY, null, MAX_2D_TRIANGLES);
        const shown = shownPart() || scene.part_start;
        if (shown) addFaces(partMesh, poseMatrix(shown.orientation_xyzw, shown.position_m), PART_COLOR, MAX_2D_TRIANGLES / 4);
        otherPoses(f).forEach((p, k) => addFaces(otherMeshes[k], poseMatrix(p.orientation_xyzw, p.position_m), OTHER_PART_COLOR, MAX_2D_TRIANGLES / 8));
        otherHandles(f).forEach(([h, k]) => addFaces(otherMeshes[k], poseMatrix(h.orientation_xyzw, h.position_m), GHOST_COLOR, MAX_2D_TRIANGLES / 16, 0.25));
        if (showSwept) addFaces(sweptMesh, IDENTITY, SWEPT_COLOR, MAX_2D_TRIANGLES / 4, 0.22);
        faces.sort((a, b) => b.depth - a.depth);
        for (const t of faces) {
          ctx.fillStyle = css(t.color, t.alpha); ctx.beginPath();
          t.q.forEach((v, k) => { const x = (v[0] / v[2] * 0.5 + 0.5) * w, y = (0.5 - v[1] / v[2] * 0.5) * h; if (k) ctx.lineTo(x, y); else ctx.moveTo(x, y); });
          ctx.fill();
        }
        const stroke = (path, color) => {
          if (!path || path.length < 2) return;
          ctx.strokeStyle = css(color); ctx.lineWidth = 1.5; ctx.beginPath();
          let pen = false;
          for (const p of path) {
            const q = project(vp, p);
            if (q[2] <= 1e-4) { pen = false; continue; }
            const x = (q[0] / q[2] * 0.5 + 0.5) * w, y = (0.5 - q[1] / q[2] * 0.5) * h;
            if (pen) ctx.lineTo(x, y); else ctx.moveTo(x, y);
            pen = true;
          }
          ctx.stroke();
        };
        stroke(scene.hand_path_m, PATH_COLOR);
        if (study) {
          stroke(study.position_m, STUDY_PATH_COLOR);
          for (const l of study.closestLines) stroke(l, CLOSEST_COLOR);
        }
        if (showVoxels) {
          const stride = Math.max(1, Math.ceil(boxes.length / 3 / 60000));
          for (let i = 0; i < boxes.length; i += 3 * stride) {
            const p = [boxes[i], boxes[i + 1], boxes[i + 2]];
            square(p, scene.box_size_m, mesh ? OVERLAY_COLOR : heightColor(p[2]));
          }
        }
        if (!f) return;
        const size = scene.shell_voxel_size_m;
        const shellPoses = partMesh && !showVoxels ? [] : [[f.handle, GHOST_COLOR, 0.3], [f.part, [0.91, 0.91, 0.91], 1]];
        for (const [pose, color, alpha] of shellPoses) {
          const m = poseMatrix(pose.orientation_xyzw, pose.position_m);
          for (let i = 0; i < shell.length; i += 3) square(transform(m, [shell[i], shell[i + 1], shell[i + 2]]), size, color, alpha);
        }
        for (const c of f.contact_points) square(c, size * 1.3, depthColor(c[3]));
        for (const c of f.interior_points) square(c, size * 1.3, [1, 0.25, 1]);
        ctx.lineWidth = 2;
        for (const l of arrows(f)) {
          const s = arrowSegments(l);
          ctx.strokeStyle = css(l.color); ctx.beginPath();
          for (let k = 0; k < 18; k += 6) {
            const a = project(vp, s.slice(k, k + 3)), b = project(vp, s.slice(k + 3, k + 6));
            if (a[2] <= 1e-4 || b[2] <= 1e-4) continue;
            ctx.moveTo((a[0] / a[2] * 0.5 + 0.5) * w, (0.5 - a[1] / a[2] * 0.5) * h);
            ctx.lineTo((b[0] / b[2] * 0.5 + 0.5) * w, (0.5 - b[1] / b[2] * 0.5) * h);
          }
          ctx.stroke();
        }
      },
      setScene() {},
    };
  }

  // ---- strip charts ----
  function chart(id, labelId, label, series) {
    return { canvas: $(id), labelEl: $(labelId), label, series, data: series.map(() => []) };
  }
  const charts = [
    chart('chart-compute', 'lbl-compute', 'frame compute (µs)', [
      { key: 'compute_us', color: '#6fc3ff' }, { key: 'recent_max_compute_us', color: '#ff8060' }]),
    chart('chart-period', 'lbl-period', 'period error (µs)', [
      { key: 'period_error_us', color: '#6fc3ff' }, { key: 'recent_max_period_error_us', color: '#ff8060' }]),
    chart('chart-contacts', 'lbl-contacts', 'contacts', [{ key: 'contacts', color: '#ffd040' }]),
    chart('chart-missed', 'lbl-missed', 'missed deadlines (total)', [{ key: 'missed_deadlines', color: '#ff5050' }]),
  ];
  function pushCharts(f) {
    for (const c of charts) {
      c.series.forEach((s, i) => { const d = c.data[i]; d.push(f[s.key]); if (d.length > HISTORY) d.shift(); });
      const latest = c.series.map((s) => fmt(f[s.key])).join(' / max ');
      c.labelEl.textContent = `${c.label}: ${latest}`;
      drawChart(c);
    }
  }
  function drawChart(c) {
    const ctx = c.canvas.getContext('2d'), w = c.canvas.width, h = c.canvas.height;
    ctx.fillStyle = '#0b0f13'; ctx.fillRect(0, 0, w, h);
    const top = Math.max(1e-9, ...c.data.flat()) * 1.1;
    ctx.fillStyle = '#56606b'; ctx.font = '10px monospace'; ctx.fillText(fmt(top), 2, 10);
    c.series.forEach((s, i) => {
      const d = c.data[i];
      ctx.strokeStyle = s.color; ctx.beginPath();
      d.forEach((v, k) => {
        const x = (k + HISTORY - d.length) / (HISTORY - 1) * w, y = h - 1 - v / top * (h - 12);
        if (k === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
      });
      ctx.stroke();
    });
  }
  const fmt = (v) => (typeof v !== 'number' ? String(v) : Math.abs(v) >= 100 || Number.isInteger(v) ? v.toFixed(0) : v.toFixed(1));
  const v3 = (a) => a.map((x) => x.toFixed(4).padStart(8)).join(' ');

  // ---- state handling ----
  // Redraws are coalesced: at most one pending, at most MAX_FPS per second, and (WebGL2) never
  // while the GPU is still busy with the previous frame, so a slow GPU (or a software one) skips
  // states instead of queueing them.
  // A browser may withhold animation frames (a page in the background, or headless Chromium on a
  // busy machine): after ANIMATION_FRAME_WAIT_MS a timer draws instead. A GPU fence that has not
  // signalled after MAX_GPU_WAIT_MS no longer holds the next draw back.
  const ANIMATION_FRAME_WAIT_MS = 250, MAX_GPU_WAIT_MS = 2000;
  let drawPending = false, lastDrawAt = -1e9;
  function requestDraw() {
    if (drawPending || !renderer) return;
    drawPending = true;
    const wait = Math.max(0, lastDrawAt + 1000 / MAX_FPS - performance.now());
    setTimeout(onNextFrame, wait);
  }
  function onNextFrame() {
    let done = false;
    const go = () => { if (!done) { done = true; drawWhenReady(); } };
    requestAnimationFrame(go);
    setTimeout(go, ANIMATION_FRAME_WAIT_MS);
  }
  function drawWhenReady() {
    const gpuBusy = renderer.busy && renderer.busy();
    if (gpuBusy && performance.now() - lastDrawAt < MAX_GPU_WAIT_MS) { setTimeout(onNextFrame, 15); return; }
    drawPending = false; lastDrawAt = performance.now(); drawNow();
  }
  // Draws once; the canvas's data-draws attribute counts the draws (tests wait on it).
  let draws = 0;
  function drawNow() { resize(); renderer.draw(); canvas.dataset.draws = String(++draws); }
  function onState(s) {
    const fresh = !state || !state.frame || !s.frame || s.frame.frame !== state.frame.frame;
    const changed = fresh || !state || state.status !== s.status;
    state = s;
    const st = $('status');
    st.className = s.status;
    st.textContent = { offline: 'offline (scene only)', waiting: 'waiting for the loop', live: 'live', stale: 'stale: no new frame' }[s.status] || s.status;
    const f = s.frame;
    if (f) {
      $('pose').textContent = [
        `frame ${f.frame}  t ${f.time_s.toFixed(3)} s`,
        `part   ${v3(f.part.position_m)} m`,
        `       q ${f.part.orientation_xyzw.map((x) => x.toFixed(3)).join(' ')}`,
        `handle ${v3(f.handle.position_m)} m`,
        `force  ${v3(f.force_n)} N`,
        `torque ${v3(f.torque_nm)} N·m`,
        `contacts ${f.contacts} (shown ${f.contact_points.length}, interior ${f.interior_points.length})`,
        `touching ${f.touching}  penetrating ${f.penetrating}  watchdog ${f.watchdog_trips}`,
        ...(scene && scene.other_parts ? scene.other_parts.flatMap((p, k) => f.others && f.others[k] ? [`${p.name}  ${v3(f.others[k].position_m)} m`, `${p.name} force ${v3(f.others[k].force_n)} N`] : []) : []),
      ].join('\n');
      if (fresh) pushCharts(f);
    } else if (s.status === 'offline') {
      $('pose').textContent = 'no loop: scene only';
    }
    if (changed) requestDraw();
  }
  // A WebSocket message is only kept; the newest is applied (parsed, the panel and charts
  // updated) at most MAX_FPS times a second. Applying each of 30 states a second on a starved
  // machine kept the page's main thread so busy that its fetches and timers waited minutes.
  let pendingState = null, applyPending = false, lastApplyAt = -Infinity;
  function receive(text) {
    lastMessageAt = performance.now();
    pendingState = text;
    if (applyPending) return;
    applyPending = true;
    setTimeout(applyState, Math.max(0, lastApplyAt + 1000 / MAX_FPS - performance.now()));
  }
  function applyState() {
    applyPending = false; lastApplyAt = performance.now();
    const text = pendingState; pendingState = null;
    if (text === null) return;
    try { onState(JSON.parse(text)); } catch (e) { console.warn(e); }
  }
  function connect() {
    let ws;
    try { ws = new WebSocket(`ws://${location.host}/ws`); } catch (e) { return; }
    ws.onmessage = (ev) => receive(ev.data);
    ws.onclose = () => setTimeout(connect, 1000);
  }
  // Without WebSocket messages (blocked, or a proxy in the way) poll /state instead.
  async function poll() {
    if (performance.now() - lastMessageAt > 500) {
      // A poll unanswered in FETCH_PATIENCE_MS is given up, so one lost request cannot stop polling.
      try { onState(await (await fetch('/state', { cache: 'no-store', signal: AbortSignal.timeout(FETCH_PATIENCE_MS) })).json()); } catch (e) { /* server gone */ }
    }
    setTimeout(poll, 200);
  }

  // ---- a study's path: scrub, play, jump to the closest approach ----
  function nearestStudyIndex(t) {
    let best = 0;
    study.time_s.forEach((u, k) => { if (Math.abs(u - t) < Math.abs(study.time_s[best] - t)) best = k; });
    return best;
  }
  function setStudyIndex(k) {
    studyIndex = Math.max(0, Math.min(study.time_s.length - 1, k | 0));
    $('scrub').value = String(studyIndex);
    const c = study.clearance_m[studyIndex];
    $('study-pose').textContent = [
      `t ${study.time_s[studyIndex].toFixed(3)} s  frame ${study.frame[studyIndex]}`,
      `part   ${v3(study.position_m[studyIndex])} m`,
      `       q ${study.orientation_xyzw[studyIndex].map((x) => x.toFixed(3)).join(' ')}`,
      `force  ${v3(study.device_force_n[studyIndex])} N`,
      `clearance ${typeof c === 'number' ? (c * 1000).toFixed(2) + ' mm' : '(not measured at this frame)'}`,
    ].join('\n');
    requestDraw();
  }
  let playTimer = null;
  function setPlaying(on) {
    if (playTimer) { clearInterval(playTimer); playTimer = null; }
    $('play').textContent = on ? 'pause' : 'play';
    if (!on) return;
    if (studyIndex >= study.time_s.length - 1) setStudyIndex(0);
    let t = study.time_s[studyIndex], last = performance.now();
    playTimer = setInterval(() => {
      const now = performance.now();
      t += (now - last) / 1000; last = now;
      let k = studyIndex;
      while (k + 1 < study.time_s.length && study.time_s[k + 1] <= t) k++;
      setStudyIndex(k);
      if (k >= study.time_s.length - 1) setPlaying(false);
    }, 1000 / MAX_FPS);
  }
  function setupStudy(s) {
    if (!s.time_s.length) return;
    study = s;
    // The closest approach: the segment between the two nearest points and a cross on each.
    study.closestLines = [];
    if (s.closest) {
      const c = s.closest, r = Math.max(scene.voxel_size_m, 1e-3);
      study.closestLines.push([c.on_part_m, c.on_object_m]);
      for (const p of [c.on_part_m, c.on_object_m]) {
        for (let a = 0; a < 3; a++) {
          const d = [0, 0, 0]; d[a] = r;
          study.closestLines.push([sub(p, d), add(p, d)]);
        }
      }
    }
    $('study').hidden = false;
    $('pose').textContent = 'no loop: a study\'s recorded path (below)';
    $('study-verdict').textContent = s.verdict;
    $('study-closest').textContent = s.closest
      ? `closest approach ${(s.closest.distance_m * 1000).toFixed(2)} mm at t = ${s.closest.time_s.toFixed(3)} s near ${s.closest.object}`
      : 'no static meshes: no clearance';
    const scrub = $('scrub');
    scrub.max = String(s.time_s.length - 1);
    scrub.addEventListener('input', () => { setPlaying(false); setStudyIndex(Number(scrub.value)); });
    $('play').addEventListener('click', () => setPlaying(!playTimer));
    const toClosest = $('to-closest');
    toClosest.disabled = !s.closest;
    toClosest.addEventListener('click', () => { setPlaying(false); setStudyIndex(nearestStudyIndex(s.closest.time_s)); });
    $('swept-toggle').hidden = !sweptMesh;
    $('swept').addEventListener('change', (e) => { showSwept = e.target.checked; requestDraw(); });
    setStudyIndex(s.closest ? nearestStudyIndex(s.closest.time_s) : 0);
  }

  // ---- camera input ----
  function resize() {
    const r = canvas.getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(r.width * dpr)), h = Math.max(1, Math.round(r.height * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  }
  let drag = null;
  canvas.addEventListener('mousedown', (e) => { drag = [e.clientX, e.clientY]; });
  window.addEventListener('mouseup', () => { drag = null; });
  window.addEventListener('mousemove', (e) => {
    if (!drag) return;
    camera.yaw -= (e.clientX - drag[0]) * 0.01;
    camera.pitch = Math.max(-1.5, Math.min(1.5, camera.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY]; requestDraw();
  });
  canvas.addEventListener('wheel', (e) => { e.preventDefault(); camera.dist *= Math.exp(e.deltaY * 0.001); requestDraw(); }, { passive: false });
  function setFollow(on) {
    camera.follow = on; $('follow').checked = on;
    if (!on && scene) {
      camera.target = scale(add(scene.bounds_min_m, scene.bounds_max_m), 0.5);
      camera.dist = len(sub(scene.bounds_max_m, scene.bounds_min_m)) * 0.8;
    } else camera.dist = Math.max(0.1, (scene ? scene.shell_voxel_size_m : 0.005) * 60);
    requestDraw();
  }
  $('follow').addEventListener('change', (e) => setFollow(e.target.checked));
  function setVoxels(on) { showVoxels = on; $('voxels').checked = on; requestDraw(); }
  $('voxels').addEventListener('change', (e) => setVoxels(e.target.checked));
  window.addEventListener('keydown', (e) => {
    if (e.key === 'f') setFollow(!camera.follow);
    if (e.key === 'v') setVoxels(!showVoxels);
    // A focused slider steps itself.
    if (study && document.activeElement !== $('scrub')) {
      if (e.key === 'ArrowLeft') { setPlaying(false); setStudyIndex(studyIndex - 1); }
      if (e.key === 'ArrowRight') { setPlaying(false); setStudyIndex(studyIndex + 1); }
    }
  });
  window.addEventListener('resize', requestDraw);

  // ---- start ----
  // The state comes first (the pose is in the page as soon as possible), then the scene, then the
  // renderer (a software WebGL context can take seconds to create).
  async function start() {
    // The page's start phase, for tests and for a person debugging a page that draws nothing.
    const phase = (p) => { document.body.dataset.phase = p; };
    // A request that fails (the network, or no answer, i.e. no headers, in FETCH_PATIENCE_MS) is
    // asked again a second later, FETCH_TRIES times in all, before the page reports an error: a
    // loaded server may close a kept-alive connection just as the next request goes out on it.
    const get = async (path, kind) => {
      if (EMBEDDED) return embedded(path);
      for (let attempt = 1; ; attempt++) {
        phase(attempt === 1 ? `fetching ${path}` : `fetching ${path} (try ${attempt} of ${FETCH_TRIES})`);
        const abort = new AbortController();
        const timer = setTimeout(() => abort.abort(), FETCH_PATIENCE_MS);
        let r;
        try {
          r = await fetch(path, { cache: 'no-store', signal: abort.signal });
        } catch (e) {
          const why = abort.signal.aborted ? `no answer in ${FETCH_PATIENCE_MS / 1000} s` : e.message;
          if (attempt >= FETCH_TRIES) throw new Error(`${path}: ${why} (${FETCH_TRIES} tries)`);
          await new Promise((done) => setTimeout(done, 1000));
          continue;
        } finally {
          clearTimeout(timer);
        }
        if (!r.ok) throw new Error(`${path}: ${r.status}`);
        phase(`reading ${path}`);
        return r[kind]();
      }
    };
    // The page's own copy of a route's data: JSON as it is, buffers decoded from base64.
    const embedded = (path) => {
      if (path === '/state') return EMBEDDED.state;
      if (path === '/scene') return EMBEDDED.scene;
      const text = EMBEDDED.files[path];
      if (typeof text !== 'string') throw new Error(`${path}: not in the page`);
      const raw = atob(text), bytes = new Uint8Array(raw.length);
      for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
      return bytes.buffer;
    };
    try {
      onState(await get('/state', 'json'));
      if (!EMBEDDED) { connect(); poll(); }
      // With no loop the frame-timing charts have nothing to show.
      if (state.status === 'offline') for (const c of document.querySelectorAll('.chart')) c.hidden = true;
      scene = await get('/scene', 'json');
      boxes = new Float32Array(await get('/scene/boxes', 'arrayBuffer'));
      shell = new Float32Array(await get('/scene/shell', 'arrayBuffer'));
      if (scene.mesh_triangles) mesh = withNormals(new Float32Array(await get('/scene/mesh', 'arrayBuffer')));
      if (scene.part_mesh_triangles) partMesh = withNormals(new Float32Array(await get('/scene/part_mesh', 'arrayBuffer')));
      if (scene.swept_mesh_triangles) sweptMesh = withNormals(new Float32Array(await get('/scene/swept_mesh', 'arrayBuffer')));
      if (scene.other_parts && scene.other_parts.length) {
        const all = new Float32Array(await get('/scene/other_part_meshes', 'arrayBuffer'));
        let at = 0;
        otherMeshes = scene.other_parts.map((p) => { const m = withNormals(all.slice(at, at + 9 * p.mesh_triangles)); at += 9 * p.mesh_triangles; return m; });
      }
    } catch (e) {
      $('status').className = 'error'; $('status').textContent = `cannot load the scene: ${e.message}`; return;
    }
    $('scene-info').textContent = `${scene.label}: ${scene.surface_voxels} Surface voxels of ${(scene.voxel_size_m * 1000).toFixed(1)} mm, ` +
      `${scene.boxes} boxes of ${(scene.box_size_m * 1000).toFixed(1)} mm; part ${scene.shell_points_total} points` +
      (mesh ? `; meshes ${scene.mesh_triangles} of ${scene.mesh_triangles_total} triangles` : '') +
      (partMesh ? `; part mesh ${scene.part_mesh_triangles} of ${scene.part_mesh_triangles_total}` : '') +
      (otherMeshes.length ? `; other parts: ${scene.other_parts.map((p) => p.name).join(', ')}` : '');
    // The voxel boxes are the view when there is no mesh, an overlay (off at first) when there is.
    setVoxels(!(mesh || partMesh));
    buildChunks();
    if (scene.study) setupStudy(scene.study);
    setFollow(!!(state && state.status !== 'offline' && scene.shell_points));
    resize();
    phase('creating the renderer');
    renderer = makeGL() || make2D();
    $('render-mode').textContent = renderer ? renderer.mode : 'none';
    phase('first draw');
    if (renderer) { renderer.setScene(); drawNow(); }
    phase('running');
  }
  start();
})();
