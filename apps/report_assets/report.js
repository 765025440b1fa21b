// pano2cad report.html: layer toggles and the three.js 3D view (inlined into the page as a module).
// Status for tests and tools: the body attribute data-view3d (pending, ready, missing, no-webgl, error).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const body = document.body;
let cspViolations = 0;
document.addEventListener('securitypolicyviolation', () => {
  cspViolations += 1;
  body.dataset.cspViolations = String(cspViolations);
});

function auditResources() {
  const names = performance.getEntriesByType('resource').map((e) => e.name)
    .filter((n) => !n.startsWith('data:') && !n.startsWith('blob:'));
  body.dataset.resources = JSON.stringify(names);
}

for (const box of document.querySelectorAll('input[data-layer]')) {
  const apply = () => {
    for (const el of document.querySelectorAll('.layer-' + box.dataset.layer)) {
      el.style.display = box.checked ? '' : 'none';
    }
  };
  box.addEventListener('change', apply);
  apply();
}

function fail(state, message) {
  body.dataset.view3d = state;
  body.dataset.view3dError = message;
  const msg = document.getElementById('view3d-msg');
  if (msg) msg.textContent = '3D view unavailable: ' + message;
  auditResources();
}

function base64ToBuffer(b64) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return bytes.buffer;
}

function canvasVariance(gl) {
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const px = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  let s = 0, s2 = 0;
  const n = w * h;
  for (let i = 0; i < px.length; i += 4) {
    const y = 0.299 * px[i] + 0.587 * px[i + 1] + 0.114 * px[i + 2];
    s += y; s2 += y * y;
  }
  const m = s / n;
  return s2 / n - m * m;
}

function start3d() {
  const glbEl = document.getElementById('glb-data');
  const view = document.getElementById('viewport');
  if (!glbEl || !view) { body.dataset.view3d = 'missing'; auditResources(); return; }
  const data = JSON.parse(document.getElementById('report-data').textContent);
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  } catch (err) {
    fail('no-webgl', 'WebGL is not available in this browser (' + err.message + ')');
    return;
  }
  const w = view.clientWidth || 800, h = view.clientHeight || 520;
  renderer.setPixelRatio(1);
  renderer.setSize(w, h);
  view.replaceChildren(renderer.domElement);

  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xf4f4f4);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8a8a, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.4);
  sun.position.set(4, 10, 6);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(60, w / h, 0.02, 500);
  const controls = new OrbitControls(camera, renderer.domElement);
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);

  new GLTFLoader().parse(base64ToBuffer(glbEl.textContent.trim()), '', (gltf) => {
    scene.add(gltf.scene);
    const box = new THREE.Box3().setFromObject(gltf.scene);
    const center = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const s = Math.max(size.x, size.y, size.z, 1.0);
    // glTF is y-up: world (x, y, z) -> (x, z, -y); the camera is at world (0, 0, floor_z + camera_height).
    const eye = new THREE.Vector3(0, (data.floor_z || 0) + (data.camera_height_m || 1.6), 0);

    const orbit = () => {
      controls.enablePan = true;
      controls.minDistance = 0.1;
      camera.position.set(center.x + 0.5 * s, center.y + 1.15 * s, center.z + 0.8 * s);
      controls.target.copy(center);
      controls.update();
      render();
    };
    const firstPerson = () => {
      // Orbit about a point just ahead of the eye: dragging turns the head, the wheel moves.
      controls.enablePan = false;
      controls.minDistance = 0.001;
      camera.position.copy(eye);
      controls.target.set(eye.x + 0.01, eye.y, eye.z);  // looking along +x, the image centre column
      controls.update();
      render();
    };
    document.getElementById('btn-orbit').addEventListener('click', orbit);
    document.getElementById('btn-fp').addEventListener('click', firstPerson);

    const gl = renderer.getContext();
    firstPerson();
    body.dataset.canvasVarianceFp = canvasVariance(gl).toFixed(2);
    orbit();
    body.dataset.canvasVariance = canvasVariance(gl).toFixed(2);
    const r = renderer.domElement.getBoundingClientRect();
    body.dataset.canvasRect = JSON.stringify([r.left + scrollX, r.top + scrollY, r.width, r.height].map(Math.round));
    body.dataset.view3d = 'ready';
    auditResources();
  }, (err) => fail('error', 'scene.glb could not be read (' + (err && err.message ? err.message : err) + ')'));
}

try {
  start3d();
} catch (err) {
  fail('error', String(err && err.message ? err.message : err));
}
