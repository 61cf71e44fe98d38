// vdrig viewer: a finished session's parameter map in WebGL2 (docs/web.md), with the shader `vdrig view` compiles
// (viewer::surface_glsl, served as the scene's glsl: the model's own GLSL and the surface shader's arithmetic):
// pinhole + Brown distortion, ray onto the surface plane, bilinear blend of the model at the four nearest texel
// centres, sub-samples per pixel axis, then y = 1 - exp(-gamma x) and sRGB. Orbit, the captured views, and at a
// captured view the photograph or |render - photo| × 4. A click (not a drag) on the surface shows the texel
// inspector's curve plot of the texel under it (viewer::pick_texel's arithmetic; the plot is the server's SVG of
// viewer::curve_figure, shown in an <img>).
'use strict';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const session = params.get('session') || '';
let gl = null, program = null, scene = null, photoTex = null, photoView = -1;
let orbit = { az: 30, zen: 35, dist: 1200 };

const kVertex = `#version 300 es
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}`;

// The fragment shader: viewer::surface_glsl as the server sends it (scene.glsl: the desktop renderer's uniforms,
// distortion, the map's model, pixel_radiance and display_srgb) between this GLSL ES header and this main.
const kHead = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2DArray;
precision highp sampler2D;
out vec4 out_colour;
uniform sampler2D u_photo;
uniform int u_display;  // 0 render, 1 photograph, 2 |render - photo| x 4
`;

const kMain = `
void main() {
  float px = gl_FragCoord.x - 0.5;
  float py = float(u_height) - gl_FragCoord.y - 0.5;  // OpenCV row from the top
  vec3 srgb = display_srgb(pixel_radiance(px, py));
  if (u_display != 0) {
    vec3 photo = texelFetch(u_photo, ivec2(int(px), int(py)), 0).rgb;
    srgb = u_display == 1 ? photo : min(abs(srgb - photo) * 4.0, vec3(1.0));
  }
  out_colour = vec4(srgb, 1.0);
}
`;

function fail(text) {
  $('viewer-error').textContent = text;
  document.body.dataset.state = 'error';
}

function compile(type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(s));
  return s;
}

function decodeFloats(b64) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; ++i) bytes[i] = bin.charCodeAt(i);
  return new Float32Array(bytes.buffer);
}

// viewer::orbit_pose: the camera at `dist` from the surface centre, toward it, rows of R = (e_az, e_zen, -d).
function orbitPose(azDeg, zenDeg, dist) {
  const a = azDeg * Math.PI / 180, z = zenDeg * Math.PI / 180;
  const ca = Math.cos(a), sa = Math.sin(a), cz = Math.cos(z), sz = Math.sin(z);
  const d = [sz * ca, sz * sa, cz];
  return { R: [-sa, ca, 0, cz * ca, cz * sa, -sz, -d[0], -d[1], -d[2]], centre: d.map((v) => v * dist) };
}

function distortJs(u, k) {
  const r2 = u[0] * u[0] + u[1] * u[1];
  const radial = 1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
  return [u[0] * radial + 2 * k[2] * u[0] * u[1] + k[3] * (r2 + 2 * u[0] * u[0]),
          u[1] * radial + k[2] * (r2 + 2 * u[1] * u[1]) + 2 * k[3] * u[0] * u[1]];
}

// viewer::pick_texel: the texel whose footprint the ray through camera pixel (x, y) (OpenCV's convention: the
// centre of the top-left pixel is 0, 0) meets on the surface plane, or null when it misses the surface.
function pickTexel(x, y, pose) {
  const c = scene.camera;
  const d = [(x - c.cx) / c.fx, (y - c.cy) / c.fy];
  let u = d.slice();
  for (let i = 0; i < 40; ++i) {
    const f = distortJs(u, c.dist);
    const step = [f[0] - d[0], f[1] - d[1]];
    u = [u[0] - step[0], u[1] - step[1]];
    if (step[0] * step[0] + step[1] * step[1] < 1e-16) break;
  }
  const n = Math.hypot(u[0], u[1], 1);
  const rc = [u[0] / n, u[1] / n, 1 / n], R = pose.R;
  const ray = [0, 1, 2].map((i) => R[i] * rc[0] + R[3 + i] * rc[1] + R[6 + i] * rc[2]);
  if (Math.abs(ray[2]) < 1e-12) return null;
  const along = -pose.centre[2] / ray[2];
  if (along <= 0) return null;
  const px = pose.centre[0] + along * ray[0], py = pose.centre[1] + along * ray[1];
  const fu = (px + 0.5 * scene.size_mm[0]) / scene.size_mm[0], fv = (py + 0.5 * scene.size_mm[1]) / scene.size_mm[1];
  if (fu < 0 || fu >= 1 || fv < 0 || fv >= 1) return null;
  return [Math.min(scene.texels[0] - 1, Math.floor(fu * scene.texels[0])),
          Math.min(scene.texels[1] - 1, Math.floor(fv * scene.texels[1]))];
}

function currentPose() {
  const choice = $('view').value;
  const view = choice === 'orbit' ? null : scene.views.find((v) => String(v.index) === choice);
  return view ? { R: view.R, centre: view.centre } : orbitPose(orbit.az, orbit.zen, orbit.dist);
}

// The inspector's plot of the texel under a click, as the server's SVG in an <img> (an image's scripts never run);
// on a refusal the server's JSON reason is shown as text.
function inspectAt(clientX, clientY) {
  if (!scene) return;
  const canvas = $('gl'), rect = canvas.getBoundingClientRect();
  const x = (clientX - rect.left) * canvas.width / rect.width - 0.5;
  const y = (clientY - rect.top) * canvas.height / rect.height - 0.5;
  const texel = pickTexel(x, y, currentPose());
  const plot = $('texel-plot'), caption = $('texel-caption');
  if (!texel) {
    caption.textContent = 'no texel there: click on the surface';
    return;
  }
  const [s, t] = texel;
  const src = `/api/viewer/texel?session=${encodeURIComponent(session)}&map=${encodeURIComponent(scene.map)}` +
              `&s=${s}&t=${t}`;
  caption.textContent = `texel ${s},${t} of ${scene.map}: loading…`;
  plot.onload = () => {
    caption.textContent = `texel ${s},${t} of ${scene.map}: observations (circles; crosses held out) within 10° ` +
                          'of the great circle through the normal and the peak, over the model';
    plot.dataset.texel = `${s},${t}`;
    plot.dataset.pixel = `${x},${y}`;
    plot.hidden = false;
  };
  plot.onerror = async () => {
    plot.hidden = true;
    delete plot.dataset.texel;
    const r = await fetch(src, { credentials: 'same-origin' }).catch(() => null);
    const body = r ? await r.json().catch(() => ({})) : {};
    caption.textContent = `texel ${s},${t}: ` + ((body.code ? body.code + ': ' : '') + (body.error || 'no plot'));
  };
  plot.src = src;
}

async function loadScene(map) {
  const q = 'session=' + encodeURIComponent(session) + (map ? '&map=' + encodeURIComponent(map) : '');
  const r = await fetch('/api/viewer/scene?' + q, { credentials: 'same-origin' });
  const body = await r.json().catch(() => ({ ok: false, error: r.status + ' ' + r.statusText }));
  if (!body.ok) return fail((body.code ? body.code + ': ' : '') + (body.error || 'no scene'));
  scene = body;
  $('title').textContent = `${session}: ${scene.map}`;
  const mapSelect = $('map');
  mapSelect.replaceChildren();
  for (const m of scene.maps) {
    const o = document.createElement('option');
    o.value = o.textContent = m;
    o.selected = m === scene.map;
    mapSelect.appendChild(o);
  }
  const viewSelect = $('view');
  const keep = viewSelect.value;
  viewSelect.replaceChildren(new Option('orbit', 'orbit'));
  for (const v of scene.views) viewSelect.appendChild(new Option(`view ${v.index}` + (v.photo ? '' : ' (no photo)'),
                                                                 String(v.index)));
  viewSelect.value = [...viewSelect.options].some((o) => o.value === keep) ? keep : 'orbit';

  const canvas = $('gl');
  canvas.width = scene.camera.width;
  canvas.height = scene.camera.height;
  gl = gl || canvas.getContext('webgl2', { preserveDrawingBuffer: true, antialias: false });
  if (!gl) return fail('this browser has no WebGL2');
  program = gl.createProgram();
  gl.attachShader(program, compile(gl.VERTEX_SHADER, kVertex));
  gl.attachShader(program, compile(gl.FRAGMENT_SHADER, kHead + scene.glsl + kMain));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) return fail('link: ' + gl.getProgramInfoLog(program));

  const [w, h] = scene.image_size;
  const tex = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
  gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGBA32F, w, h, scene.layers, 0, gl.RGBA, gl.FLOAT,
                decodeFloats(scene.params_base64));
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  photoView = -1;
  await draw();
}

async function loadPhoto(view) {
  if (photoView === view) return true;
  const img = new Image();
  img.src = `/api/viewer/photo?session=${encodeURIComponent(session)}&view=${view}`;
  try {
    await img.decode();
  } catch (e) {
    return false;
  }
  photoTex = photoTex || gl.createTexture();
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_2D, photoTex);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, img);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  photoView = view;
  return true;
}

async function draw() {
  if (!scene || !program) return;
  const choice = $('view').value;
  const view = choice === 'orbit' ? null : scene.views.find((v) => String(v.index) === choice);
  const pose = view ? { R: view.R, centre: view.centre } : orbitPose(orbit.az, orbit.zen, orbit.dist);
  let display = Number($('display').value);
  if (display !== 0 && !(view && view.photo && await loadPhoto(view.index))) display = 0;
  const c = scene.camera;
  gl.viewport(0, 0, c.width, c.height);
  gl.useProgram(program);
  const loc = (n) => gl.getUniformLocation(program, n);
  gl.uniform1i(loc('u_params'), 0);
  gl.uniform1i(loc('u_photo'), 1);
  gl.uniform2i(loc('u_texels'), scene.texels[0], scene.texels[1]);
  gl.uniform2f(loc('u_size_mm'), scene.size_mm[0], scene.size_mm[1]);
  gl.uniform4f(loc('u_intrinsics'), c.fx, c.fy, c.cx, c.cy);
  gl.uniform1fv(loc('u_dist'), new Float32Array(c.dist));
  // column-major mat3 of R^T: column j is row j of R, so R's row-major array is R^T's column-major one.
  gl.uniformMatrix3fv(loc('u_cam_to_surface'), false, new Float32Array(pose.R));
  gl.uniform3f(loc('u_centre'), pose.centre[0], pose.centre[1], pose.centre[2]);
  gl.uniform1i(loc('u_samples'), Math.max(1, Math.min(4, Number($('samples').value) || 2)));
  gl.uniform1i(loc('u_height'), c.height);
  gl.uniform1f(loc('u_gamma'), Number($('gamma').value) || 1);
  gl.uniform1i(loc('u_display'), display);
  gl.clearColor(0.05, 0.05, 0.06, 1);
  gl.clear(gl.COLOR_BUFFER_BIT);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  gl.finish();
  const what = ['render', 'photograph', 'difference ×4'][display];
  $('viewer-status').textContent = (view ? `view ${view.index}` :
    `orbit: azimuth ${orbit.az}°, zenith ${orbit.zen}°, ${orbit.dist} mm`) + `, ${what}, ${scene.model}`;
  const canvas = $('gl');
  canvas.dataset.view = view ? String(view.index) : 'orbit';
  canvas.dataset.display = String(display);
  document.body.dataset.state = 'drawn';
  document.body.dataset.draws = String(Number(document.body.dataset.draws || 0) + 1);
}

function fromSliders() {
  orbit = { az: Number($('azimuth').value), zen: Number($('zenith').value), dist: Number($('distance').value) };
  if ($('view').value !== 'orbit') $('view').value = 'orbit';
  draw();
}

$('map').addEventListener('change', () => loadScene($('map').value).catch((e) => fail(String(e))));
for (const id of ['view', 'display', 'gamma', 'samples']) $(id).addEventListener('change', () => draw());
for (const id of ['azimuth', 'zenith', 'distance']) $(id).addEventListener('input', fromSliders);
let drag = null, press = null;
$('gl').addEventListener('pointerdown', (e) => { drag = press = [e.clientX, e.clientY]; });
window.addEventListener('pointerup', () => { drag = null; });
// A click that did not move (a drag orbits): the texel under it.
$('gl').addEventListener('click', (e) => {
  if (press && Math.hypot(e.clientX - press[0], e.clientY - press[1]) <= 3) inspectAt(e.clientX, e.clientY);
});
$('gl').addEventListener('pointermove', (e) => {
  if (!drag) return;
  if (Math.hypot(e.clientX - press[0], e.clientY - press[1]) <= 3) return;  // still a click
  $('azimuth').value = String(Number($('azimuth').value) - (e.clientX - drag[0]) * 0.5);
  $('zenith').value = String(Number($('zenith').value) + (e.clientY - drag[1]) * 0.3);
  drag = [e.clientX, e.clientY];
  fromSliders();
});
$('gl').addEventListener('wheel', (e) => {
  e.preventDefault();
  $('distance').value = String(Number($('distance').value) * (e.deltaY > 0 ? 1.1 : 1 / 1.1));
  fromSliders();
}, { passive: false });

if (!session) fail('no session: open the viewer from the console\'s session list');
else loadScene(params.get('map') || '').catch((e) => fail(String(e)));
