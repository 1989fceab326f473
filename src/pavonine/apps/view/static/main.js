// pavonine view: the page. Orbit camera, sun and sky controls, variants, picking, render button.
// URL parameters (for scripted views): eye=x,y,z target=x,y,z fov=deg sun=x,y,z hud=0 lod=…
import * as THREE from './vendor/three.min.js';
import { OrbitControls } from './vendor/three.min.js';
import { lighting } from './feather.js';
import { loadScene } from './loader.js';

const params = new URLSearchParams(location.search);
const vector = (name) => (params.get(name) ? params.get(name).split(',').map(Number) : null);
const $ = (id) => document.getElementById(id);
const hud = params.get('hud') !== '0';
if (!hud) document.body.classList.add('bare');

const canvas = $('live');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, alpha: false });
renderer.outputColorSpace = THREE.LinearSRGBColorSpace;  // the shaders encode sRGB themselves
renderer.setPixelRatio(1);
const camera = new THREE.PerspectiveCamera(40, 1, 0.1, 1000);
const controls = new OrbitControls(camera, canvas);
const world = new THREE.Scene();
let current = null;
let selections = {};

const srgb = (c) => (c <= 0.0031308 ? 12.92 * c : 1.055 * c ** (1 / 2.4) - 0.055);
function setBackground() {
  const s = lighting.skyRadiance.value;
  renderer.setClearColor(new THREE.Color(srgb(s.x), srgb(s.y), srgb(s.z)), 1);
}

function resize() {
  const box = $('stage').getBoundingClientRect();
  const w = Math.max(1, Math.floor(box.width));
  const h = Math.max(1, Math.floor(box.height));
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  draw();
}

let queued = false;
function draw() {
  if (queued) return;
  queued = true;
  requestAnimationFrame(() => {
    queued = false;
    renderer.render(world, camera);
  });
}

// -- sun and sky ---------------------------------------------------------------------------
const deg = Math.PI / 180;
let skyBase = [0.06, 0.08, 0.11];
let sunBase = [Math.PI, Math.PI, Math.PI];
function sunFromControls() {
  const az = Number($('sun-azimuth').value) * deg;
  const el = Number($('sun-elevation').value) * deg;
  lighting.sunDirection.value.set(Math.cos(el) * Math.sin(az), Math.sin(el), Math.cos(el) * Math.cos(az));
  const e = Number($('sun-strength').value);
  lighting.sunIrradiance.value.set(sunBase[0] * e, sunBase[1] * e, sunBase[2] * e);
  const s = Number($('sky-strength').value);
  const tint = new THREE.Color($('sky-colour').value);  // sRGB swatch → linear
  tint.convertSRGBToLinear();
  const peak = Math.max(...skyBase, 1e-9);
  lighting.skyRadiance.value.set(tint.r * peak * s, tint.g * peak * s, tint.b * peak * s);
  $('sun-readout').textContent = `${$('sun-azimuth').value}°, ${$('sun-elevation').value}°`;
  setBackground();
  draw();
}
function setSunControls(direction) {
  const [x, y, z] = direction;
  $('sun-azimuth').value = Math.round(Math.atan2(x, z) / deg);
  $('sun-elevation').value = Math.round(Math.asin(Math.max(-1, Math.min(1, y))) / deg);
}
function setSky(radiance) {
  skyBase = radiance;
  const peak = Math.max(...radiance, 1e-9);
  const c = new THREE.Color(radiance[0] / peak, radiance[1] / peak, radiance[2] / peak);
  c.convertLinearToSRGB();
  $('sky-colour').value = `#${c.getHexString()}`;
}

// -- picking: class and gradation under the cursor -------------------------------------------
const raycaster = new THREE.Raycaster();
function pick(event) {
  if (!current) return;
  const box = canvas.getBoundingClientRect();
  const p = new THREE.Vector2(((event.clientX - box.left) / box.width) * 2 - 1,
                              -((event.clientY - box.top) / box.height) * 2 + 1);
  raycaster.setFromCamera(p, camera);
  const hit = raycaster.intersectObjects(current.group.children, false)
    .find((h) => h.object.userData.material.readers && h.uv);
  if (!hit) { $('pick').textContent = '—'; return; }
  const { readers, entry } = hit.object.userData.material;
  const n = entry.tableMeta.classes;
  const grey = readers.ocellar ? readers.ocellar(hit.uv.x, hit.uv.y) : 1;
  const k = Math.min(n - 1, Math.max(0, Math.round((1 - grey) * (n - 1))));
  const t = readers.gradation ? readers.gradation(hit.uv.x, hit.uv.y) : 0;
  const w = readers.melanin ? readers.melanin(hit.uv.x, hit.uv.y) : 1;
  $('pick').textContent = `class ${k} · gradation ${t.toFixed(2)} · structural ${w.toFixed(2)}`;
}
let pickPending = null;
canvas.addEventListener('pointermove', (event) => {
  if (pickPending) return;
  pickPending = requestAnimationFrame(() => { pickPending = null; pick(event); });
});

// -- variants ---------------------------------------------------------------------------------
function variantControls(variants) {
  const holder = $('variants');
  holder.replaceChildren();
  for (const [name, { choices, selection }] of Object.entries(variants)) {
    const label = document.createElement('label');
    label.textContent = `${name} `;
    const select = document.createElement('select');
    select.id = `variant-${name}`;
    for (const choice of choices) select.add(new Option(choice, choice, false, choice === selection));
    select.addEventListener('change', () => { selections[name] = select.value; load(false); });
    label.append(select);
    holder.append(label);
  }
}

async function load(first) {
  $('status').textContent = 'loading…';
  const loaded = await loadScene(selections);
  if (current) world.remove(current.group);
  current = loaded;
  world.add(loaded.group);
  const d = loaded.description;
  $('title').textContent = d.stage.split('/').pop();
  $('warnings').textContent = d.warnings.join('\n');
  for (const [name, v] of Object.entries(d.variants)) selections[name] = v.selection;
  variantControls(d.variants);
  if (first) {
    const eye = vector('eye') || d.camera.eye;
    const target = vector('target') || d.camera.target;
    camera.fov = Number(params.get('fov')) || d.camera.fov;
    camera.near = Math.max(1e-3, d.camera.radius * 0.01);
    camera.far = d.camera.radius * 40 + new THREE.Vector3(...eye).distanceTo(new THREE.Vector3(...target));
    camera.position.set(...eye);
    controls.target.set(...target);
    camera.updateProjectionMatrix();
    controls.update();
    sunBase = d.sun.irradiance.map((e) => e / Math.PI);
    setSunControls(vector('sun') || d.sun.direction);
    setSky(d.sky.radiance);
    sunFromControls();
    if (vector('sun')) lighting.sunDirection.value.set(...vector('sun')).normalize();
  }
  $('status').textContent = `${d.meshes.length} meshes`;
  resize();
}

// -- render this view --------------------------------------------------------------------------
function viewState() {
  const e = lighting.sunIrradiance.value;
  const s = lighting.skyRadiance.value;
  return {
    eye: camera.position.toArray(),
    target: controls.target.toArray(),
    up: camera.up.toArray(),
    fov: camera.fov,
    sun: lighting.sunDirection.value.toArray(),
    irradiance: [e.x, e.y, e.z],
    sky: [s.x, s.y, s.z],
    variants: { ...selections },
  };
}
async function renderView(width, height, spp) {
  const aspect = camera.aspect;
  const long = Number($('render-size').value);
  const w = width || (aspect >= 1 ? long : Math.round(long * aspect));
  const h = height || (aspect >= 1 ? Math.round(long / aspect) : long);
  const body = { ...viewState(), width: w, height: h };
  if (spp) body.spp = spp;
  $('render-status').textContent = 'rendering…';
  $('render-button').disabled = true;
  const started = performance.now();
  try {
    const response = await fetch('/api/render', {
      method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body),
    });
    if (!response.ok) throw new Error(await response.text());
    const blob = await response.blob();
    $('render-image').src = URL.createObjectURL(blob);
    $('render-image').alt = `pavonine render ${w}×${h}`;
    $('render-image').hidden = false;
    $('render-hint').hidden = true;
    $('render-status').textContent = `pavonine render ${w}×${h}: ${((performance.now() - started) / 1000).toFixed(1)} s`;
    resize();
    return blob;
  } catch (error) {
    $('render-status').textContent = String(error.message || error).trim();
    throw error;
  } finally {
    $('render-button').disabled = false;
  }
}

for (const id of ['sun-azimuth', 'sun-elevation', 'sun-strength', 'sky-strength', 'sky-colour']) {
  $(id).addEventListener('input', sunFromControls);
}
$('render-button').addEventListener('click', () => renderView().catch(() => {}));
controls.addEventListener('change', draw);
window.addEventListener('resize', resize);

const ready = load(true).then(() => true, (error) => {
  $('status').textContent = String(error.message || error);
  throw error;
});

// For scripts and tests: a frame as a PNG data URL, the mean frame time, the view, a render.
window.pavonine = {
  ready,
  frame() {
    renderer.render(world, camera);
    return canvas.toDataURL('image/png');
  },
  frameTimes: [],
  benchmark(frames = 20, flat = false, warmup = 2) {
    // The median time of a frame (drawn and read back, so the GPU has finished it) after
    // `warmup` frames, the camera turning a little each frame; every timed frame, sorted, is
    // left in frameTimes. flat: the yardstick, the same meshes in one unlit colour (what any
    // viewer pays).
    const saved = world.overrideMaterial;
    if (flat) world.overrideMaterial = new THREE.MeshBasicMaterial({ color: 0x808080, side: THREE.DoubleSide });
    const gl = renderer.getContext();
    const pixel = new Uint8Array(4);
    const axis = new THREE.Vector3(0, 1, 0);
    const times = [];
    for (let i = 0; i < warmup + frames; i += 1) {
      const start = performance.now();
      camera.position.applyAxisAngle(axis, 0.002);
      camera.lookAt(controls.target);
      renderer.render(world, camera);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
      if (i >= warmup) times.push(performance.now() - start);
    }
    world.overrideMaterial = saved;
    times.sort((a, b) => a - b);
    window.pavonine.frameTimes = times;
    const mid = times.length >> 1;
    return times.length % 2 ? times[mid] : 0.5 * (times[mid - 1] + times[mid]);
  },
  view: viewState,
  renderView,
  orbit(degrees) {  // turn the camera about the vertical through the target
    const offset = camera.position.clone().sub(controls.target);
    offset.applyAxisAngle(new THREE.Vector3(0, 1, 0), (degrees * Math.PI) / 180);
    camera.position.copy(controls.target).add(offset);
    controls.update();
    return camera.position.toArray();
  },
};
