// The stage as /api/scene.json describes it: meshes (binary buffers), materials, maps, tables.
import * as THREE from './vendor/three.min.js';
import {
  albedoTexture, brdfTexture, featherMaterial, packMaps, previewMaterial,
} from './feather.js';

async function fetchOk(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: ${response.status} ${await response.text()}`);
  return response;
}

function loadImage(url) {
  return new Promise((resolve, reject) => {
    const image = new Image();
    image.onload = () => resolve(image);
    image.onerror = () => reject(new Error(`${url}: cannot load`));
    image.src = url;
  });
}

/** Grey levels of an image for picking (the class and gradation under the cursor). */
function greyReader(image) {
  const canvas = document.createElement('canvas');
  canvas.width = image.width;
  canvas.height = image.height;
  const context = canvas.getContext('2d', { willReadFrequently: true });
  context.drawImage(image, 0, 0);
  const pixels = context.getImageData(0, 0, image.width, image.height).data;
  return (u, v) => {
    const x = Math.min(image.width - 1, Math.max(0, Math.floor(u * image.width)));
    const y = Math.min(image.height - 1, Math.max(0, Math.floor((1 - v) * image.height)));
    return pixels[(y * image.width + x) * 4] / 255;
  };
}

async function material(entry) {
  if (entry.kind !== 'feather') return { entry, make: (inst) => previewMaterial(entry, inst) };
  const [table, albedo, ...images] = await Promise.all([
    fetchOk(entry.table).then((r) => r.arrayBuffer()),
    fetchOk(entry.albedo).then((r) => r.arrayBuffer()),
    ...Object.values(entry.maps).map(loadImage),
  ]);
  const named = Object.fromEntries(Object.keys(entry.maps).map((k, i) => [k, images[i]]));
  const texture = brdfTexture(table, entry.tableMeta);
  const maps = {
    ocellar: named.ocellar, packed: packMaps(named), albedo: albedoTexture(albedo, entry.tableMeta),
  };
  const readers = {};
  for (const name of ['ocellar', 'gradation', 'melanin']) {
    if (named[name]) readers[name] = greyReader(named[name]);
  }
  return { entry, readers, make: (inst) => featherMaterial(entry, texture, maps, inst) };
}

function geometry(buffer, layout) {
  const f32 = (name) => new Float32Array(buffer, layout[name][0], layout[name][1]);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(f32('position'), 3));
  g.setAttribute('normal', new THREE.BufferAttribute(f32('normal'), 3));
  if (layout.uv) g.setAttribute('uv', new THREE.BufferAttribute(f32('uv'), 2));
  if (layout.barb) g.setAttribute('barb', new THREE.BufferAttribute(f32('barb'), 3));
  g.setIndex(new THREE.BufferAttribute(new Uint32Array(buffer, layout.index[0], layout.index[1]), 1));
  g.computeBoundingSphere();
  return g;
}

/** Load the stage for the variant selections: ``{ description, group, materials }``. */
export async function loadScene(selections) {
  const query = new URLSearchParams(selections).toString();
  const description = await (await fetchOk(`/api/scene.json?${query}`)).json();
  const materials = await Promise.all(description.materials.map(material));
  const group = new THREE.Group();
  await Promise.all(description.meshes.map(async (mesh) => {
    const buffer = await (await fetchOk(mesh.url)).arrayBuffer();
    const g = geometry(buffer, mesh.layout);
    const m = materials[mesh.material];
    let object;
    if (mesh.layout.instances) {
      const matrices = new Float32Array(buffer, mesh.layout.instances[0], mesh.layout.instances[1]);
      const count = matrices.length / 16;
      object = new THREE.InstancedMesh(g, m.make(true), count);
      object.instanceMatrix.array.set(matrices);
      object.instanceMatrix.needsUpdate = true;
      let feather;
      if (mesh.layout.instanceFeather) {
        const [offset, n] = mesh.layout.instanceFeather;
        feather = new Float32Array(buffer, offset, n);
      } else {
        feather = new Float32Array(count * 2);
        for (let i = 1; i < feather.length; i += 2) feather[i] = 1;  // offset 0, scale 1
      }
      g.setAttribute('instanceFeather', new THREE.InstancedBufferAttribute(feather, 2));
      object.computeBoundingSphere();
    } else {
      object = new THREE.Mesh(g, m.make(false));
    }
    object.name = mesh.path;
    object.userData.material = m;
    object.frustumCulled = false;
    group.add(object);
  }));
  return { description, group, materials };
}
