// Renders an exported .gltf with three.js (its GLTFLoader and WebGLRenderer, npm three, pinned in package.json) in
// Debian's headless chromium driven by puppeteer-core: the peer renderer of tests/pipeline/test_gltf_three.cpp.
// The page, three.js and the export's files are served to the browser by request interception from
// http://vdrig.invalid/ (no server, no network); the glTF is loaded by URL exactly as written.
//   node three_render.mjs CHROMIUM PROFILE_DIR JOB.json
// JOB: {"gltf": path, "width": W, "height": H, "light": {"position": [x, y, z], "intensity": [r, g, b]},
//       "views": [{"position": [x, y, z], "target": [x, y, z], "up": [x, y, z], "fov_y_deg": f,
//                  "flip_green": false}, ...]}
// in glTF's frame (metres, Y up). The light is a three.js PointLight with decay 2 and no cut-off: irradiance
// intensity * cos / d^2. Each view is rendered into a float render target with no tone mapping (linear radiance)
// and read back bottom row first. Prints one JSON line {"views": [[r, g, b, a, ...], ...], "info": {...}} on stdout;
// exits 1 with the reason on a failure.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

const [chromium, profile, jobFile] = process.argv.slice(2);
const job = JSON.parse(fs.readFileSync(jobFile, 'utf8'));
const here = path.dirname(fileURLToPath(import.meta.url));
const threeRoot = path.join(here, 'node_modules', 'three');
const exportDir = path.dirname(job.gltf);
const origin = 'http://vdrig.invalid';

const page_html = `<!doctype html><html><head><meta charset="utf-8">
<script type="importmap">{"imports": {"three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
window.renderViews = async (job) => {
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  renderer.setSize(job.width, job.height, false);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.setClearColor(0x000000, 1);
  const gltf = await new GLTFLoader().loadAsync('/export/' + job.gltfName);
  const scene = gltf.scene;
  const light = new THREE.PointLight(0xffffff, 1, 0, 2);
  const m = Math.max(...job.light.intensity);
  light.color.setRGB(job.light.intensity[0] / m, job.light.intensity[1] / m, job.light.intensity[2] / m,
                     THREE.LinearSRGBColorSpace);
  light.intensity = m;
  light.position.set(...job.light.position);
  scene.add(light);
  const target = new THREE.WebGLRenderTarget(job.width, job.height, { type: THREE.FloatType });
  let material = null;
  scene.traverse((o) => { if (o.isMesh) material = o.material; });
  const greenScale = material.normalScale ? material.normalScale.y : 1;
  const views = [];
  for (const v of job.views) {
    // "flip_green": the normal map's green channel negated (the other tangent-space convention), as a control.
    if (material.normalScale) material.normalScale.y = v.flip_green ? -greenScale : greenScale;
    const camera = new THREE.PerspectiveCamera(v.fov_y_deg, job.width / job.height, 0.01, 100);
    camera.position.set(...v.position);
    camera.up.set(...v.up);
    camera.lookAt(...v.target);
    camera.updateMatrixWorld();
    renderer.setRenderTarget(target);
    renderer.render(scene, camera);
    const pixels = new Float32Array(job.width * job.height * 4);
    renderer.readRenderTargetPixels(target, 0, 0, job.width, job.height, pixels);
    views.push(Array.from(pixels));
  }
  if (material.normalScale) material.normalScale.y = greenScale;
  return { views, info: { revision: THREE.REVISION, material: material.type,
                          normalMap: !!material.normalMap, normalScale: [material.normalScale.x, material.normalScale.y],
                          tangents: 'tangent' in (scene.getObjectByProperty('isMesh', true).geometry.attributes),
                          specularIntensity: material.specularIntensity, roughness: material.roughness } };
};
window.ready = true;
</script></head><body></body></html>`;

const types = { '.js': 'text/javascript', '.json': 'application/json', '.gltf': 'model/gltf+json',
                '.bin': 'application/octet-stream', '.png': 'image/png', '.html': 'text/html' };
function serve(url) {
  const p = new URL(url).pathname;
  if (p === '/' || p === '/index.html') return { body: page_html, type: types['.html'] };
  let file = null;
  if (p.startsWith('/three/')) file = path.join(threeRoot, p.slice('/three/'.length));
  if (p.startsWith('/export/')) file = path.join(exportDir, decodeURIComponent(p.slice('/export/'.length)));
  if (!file || !fs.existsSync(file)) return null;
  return { body: fs.readFileSync(file), type: types[path.extname(file)] || 'application/octet-stream' };
}

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  userDataDir: profile,
  args: ['--no-sandbox', '--no-first-run', '--disable-dev-shm-usage', '--use-angle=swiftshader',
         '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
let code = 0;
try {
  const page = await browser.newPage();
  page.setDefaultTimeout(60000);
  const errors = [];
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('pageerror', (e) => errors.push('page error: ' + e.message));
  await page.setRequestInterception(true);
  page.on('request', (request) => {
    if (!request.url().startsWith(origin)) return request.abort();
    if (new URL(request.url()).pathname === '/favicon.ico') return request.respond({ status: 204, body: '' });
    const found = serve(request.url());
    if (!found) {
      errors.push('not served: ' + request.url());
      return request.respond({ status: 404, body: 'not found' });
    }
    return request.respond({ status: 200, contentType: found.type, body: found.body });
  });
  await page.goto(origin + '/index.html');
  await page.waitForFunction(() => window.ready === true);
  const result = await page.evaluate((j) => window.renderViews(j), { ...job, gltfName: path.basename(job.gltf) });
  if (errors.length) throw new Error('browser errors: ' + errors.join('; '));
  process.stdout.write(JSON.stringify(result) + '\n');
} catch (e) {
  console.error(String(e && e.stack ? e.stack : e));
  code = 1;
} finally {
  await browser.close();
}
process.exit(code);
