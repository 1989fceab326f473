// The feather material: the BRDF table of pavonine/apps/view/tables.py sampled per pixel.
// f = [c T_long + (1 - c) T_short](k, t, theta_d, |s_x|) * exp(-s_y^2/a_y^2) / (a_y pi h_z^4)
//     * G1(wi) G1(wo) / (4 cos_i cos_o), mixed with melanin brown by the melanin map (tables.py).
import * as THREE from './vendor/three.min.js';

const VERTEX = /* glsl */ `
precision highp float;
uniform mat4 modelMatrix, viewMatrix, projectionMatrix;
in vec3 position;
in vec3 normal;
#ifdef FEATHER
in vec2 uv;
in vec3 barb;
out vec2 vUv;
out vec3 vBarb;
#endif
#ifdef INSTANCED
in mat4 instanceMatrix;
in vec2 instanceFeather;  // gradation offset, structural scale (1 when absent: see below)
#endif
out vec3 vWorld;
out vec2 vFeather;
out vec3 vNormal;
void main() {
  mat4 m = modelMatrix;
  vFeather = vec2(0.0, 1.0);
#ifdef INSTANCED
  m = m * instanceMatrix;
  vFeather = instanceFeather;
#endif
  vec4 world = m * vec4(position, 1.0);
  vWorld = world.xyz;
  vNormal = mat3(m) * normal;  // world-space buffers; instances: rotation and uniform scale
#ifdef FEATHER
  vUv = uv;
  vBarb = mat3(m) * barb;
#endif
  gl_Position = projectionMatrix * viewMatrix * world;
}`;

const FRAGMENT = /* glsl */ `
precision highp float;
precision highp sampler3D;
#define PI 3.14159265358979
uniform vec3 cameraPosition;
uniform vec3 sunDirection, sunIrradiance, skyRadiance;
uniform vec3 baseColor;
in vec3 vWorld;
in vec3 vNormal;
in vec2 vFeather;
out vec4 outColor;
#ifdef FEATHER
in vec2 vUv;
in vec3 vBarb;
uniform sampler3D brdf;
uniform sampler2D ocellarMap;  // nearest, as the renderer reads it
uniform sampler2D packedMaps;  // bilinear: gradation, angle, melanin, alpha
uniform sampler2D albedoMap;   // tables.sky_albedo: x = view angle, y = class and gradation
uniform float albedoSteps;
uniform float classes, gradations, thetaSteps, slopeSteps, layers, slopeMax, alphaXG, alphaY;
uniform vec3 melaninRgb;
const float FADE_T2 = 0.011054; // tan(6 deg)^2, brdf.ORIENTATION_FADE_DEG

float acosFast(float x) {
  // acos on [0, 1] by Abramowitz & Stegun 4.4.45 (|error| <= 6.7e-5 rad, a 400th of a table
  // step), cheaper than acos in software WebGL
  return sqrt(1.0 - x) * (1.5707288 + x * (-0.2121144 + x * (0.0742610 - 0.0187293 * x)));
}

float smithG1(vec3 w, float hdotw) {
  // Beckmann Smith G1 by Walter et al. 2007's rational fit (Eq. 27), tables.smith_g1_walter
  if (hdotw * w.z <= 0.0 || w.z <= 0.0) return 0.0;
  float a = w.z * inversesqrt(max(w.x * w.x * alphaXG * alphaXG + w.y * w.y * alphaY * alphaY, 1e-20));
  return a >= 1.6 ? 1.0 : (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a);
}

vec3 spectral(float k, float t, float axis, float thetaD, float slope) {
  // z = (axis * classes + k) * gradations + t: the filtering in z lerps the gradation steps
  vec3 p = vec3((min(slope / slopeMax, 1.0) * (slopeSteps - 1.0) + 0.5) / slopeSteps,
                (thetaD / (0.5 * PI) * (thetaSteps - 1.0) + 0.5) / thetaSteps,
                ((axis * classes + k) * gradations + clamp(t, 0.0, 1.0) * (gradations - 1.0)
                 + 0.5) / layers);
  return texture(brdf, p).rgb;
}

vec3 structural(vec3 wi, vec3 wo, float k, float t) {
  if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
  vec3 h = normalize(wi + wo);
  float cosD = clamp(dot(wi, h), 0.0, 1.0);
  float thetaD = acosFast(cosD);
  float sx = abs(h.x / h.z), sy = h.y / h.z;
#ifdef SHARED_AXES
  vec3 r = spectral(k, t, 0.0, thetaD, sx);
#else
  float hxx = h.x * h.x, hyy = h.y * h.y;
  float c = 0.5 + 0.5 * (hxx - hyy) / (hxx + hyy + FADE_T2 * h.z * h.z + 1e-30);
  vec3 r = c * spectral(k, t, 0.0, thetaD, sx) + (1.0 - c) * spectral(k, t, 1.0, thetaD, sx);
#endif
  float hz2 = h.z * h.z;
  float d = exp(-(sy * sy) / (alphaY * alphaY)) / (alphaY * PI * hz2 * hz2);
  float g = smithG1(wi, cosD) * smithG1(wo, dot(wo, h));
  return r * d * g / max(4.0 * wi.z * wo.z, 1e-12);
}
#endif

vec3 srgbEncode(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}

void main() {
  vec3 n = normalize(vNormal);
  vec3 v = normalize(cameraPosition - vWorld);
  vec3 l = normalize(sunDirection);
  vec3 radiance;
  float alpha = 1.0;
#ifdef FEATHER
  vec4 maps = texture(packedMaps, vUv);
  if (maps.a < 0.004) discard;  // the gaps between barbs: nothing to shade
  float grey = texture(ocellarMap, vUv).r;
  float k = clamp(floor((1.0 - grey) * (classes - 1.0) + 0.5), 0.0, classes - 1.0);
  // per-instance primvars as feather_bsdf.py applies them: t + offset, share × scale, clipped
  float t = clamp(maps.r + vFeather.x, 0.0, 1.0), turn = maps.g * PI;
  float share = clamp(maps.b * vFeather.y, 0.0, 1.0);
  alpha = maps.a;
  // The barbule's long axis: the barb direction turned by the angle map about the normal
  // (counter-clockwise seen from the front), as feather_bsdf.py reads it.
  vec3 b = vBarb - n * dot(vBarb, n);
  b = dot(b, b) > 1e-12 ? normalize(b) : normalize(abs(n.x) < 0.9 ? cross(n, vec3(1, 0, 0))
                                                                  : cross(n, vec3(0, 1, 0)));
  vec3 x = cos(turn) * b + sin(turn) * cross(n, b);
  if (dot(n, v) < 0.0) n = -n;  // two-sided: seen from behind, the mirror image
  vec3 y = cross(n, x);
  vec3 wi = vec3(dot(v, x), dot(v, y), dot(v, n));
  vec3 wo = vec3(dot(l, x), dot(l, y), dot(l, n));
  vec3 f = share * structural(wi, wo, k, t) + (1.0 - share) * melaninRgb / PI;
  radiance = f * sunIrradiance * max(wo.z, 0.0);
  float viewAngle = acosFast(clamp(wi.z, 0.0, 1.0)) / radians(89.0);
  vec2 at = vec2((min(viewAngle, 1.0) * (albedoSteps - 1.0) + 0.5) / albedoSteps,
                 (k * gradations + clamp(t, 0.0, 1.0) * (gradations - 1.0) + 0.5)
                     / (classes * gradations));
  vec3 skyAlbedo = share * texture(albedoMap, at).rgb + (1.0 - share) * melaninRgb;
  radiance += skyRadiance * skyAlbedo;
#else
  if (dot(n, v) < 0.0) n = -n;
  radiance = baseColor / PI * sunIrradiance * max(dot(n, l), 0.0) + baseColor * skyRadiance;
#endif
  outColor = vec4(srgbEncode(radiance), alpha);
}`;

function ocellarTexture(image) {
  const texture = new THREE.Texture(image);
  texture.colorSpace = THREE.NoColorSpace;
  texture.flipY = true;
  texture.generateMipmaps = false;
  texture.minFilter = texture.magFilter = THREE.NearestFilter;
  texture.wrapS = texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.needsUpdate = true;
  return texture;
}

/** Gradation, angle, melanin and alpha maps in one RGBA texture (bottom row first). */
export function packMaps(images) {
  const NEUTRAL = { gradation: 0, angle: 0, melanin: 255, alpha: 255 };
  const names = Object.keys(NEUTRAL);
  const first = images.alpha || names.map((n) => images[n]).find(Boolean);
  const width = first ? first.width : 1;
  const height = first ? first.height : 1;
  const canvas = document.createElement('canvas');
  canvas.width = width;
  canvas.height = height;
  const context = canvas.getContext('2d', { willReadFrequently: true });
  const data = new Uint8Array(width * height * 4);
  names.forEach((name, channel) => {
    if (!images[name]) {
      for (let i = channel; i < data.length; i += 4) data[i] = NEUTRAL[name];
      return;
    }
    context.clearRect(0, 0, width, height);
    context.drawImage(images[name], 0, 0, width, height);
    const grey = context.getImageData(0, 0, width, height).data;
    for (let y = 0; y < height; y += 1) {
      const from = y * width * 4;
      const to = (height - 1 - y) * width * 4;
      for (let x = 0; x < width * 4; x += 4) data[to + x + channel] = grey[from + x];
    }
  });
  const texture = new THREE.DataTexture(data, width, height, THREE.RGBAFormat);
  texture.colorSpace = THREE.NoColorSpace;
  texture.minFilter = texture.magFilter = THREE.LinearFilter;
  texture.wrapS = texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.needsUpdate = true;
  return texture;
}

/** Half floats as 32-bit floats: software WebGL (SwiftShader) filters float textures about a
 * quarter faster than half-float ones (benchmarks/bench_view.py), for twice the memory. */
function singles(buffer) {
  return Float32Array.from(new Uint16Array(buffer), THREE.DataUtils.fromHalfFloat);
}

/** The 2D texture of a table's sky albedo (RGBA half floats from /api/<key>/albedo/<i>.bin). */
export function albedoTexture(buffer, meta) {
  const texture = new THREE.DataTexture(
    singles(buffer), meta.albedoSteps, meta.classes * meta.gradations, THREE.RGBAFormat,
    THREE.FloatType);
  texture.minFilter = texture.magFilter = THREE.LinearFilter;
  texture.wrapS = texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.needsUpdate = true;
  return texture;
}

/** The 3D texture of a BRDF table (RGBA half floats from /api/<key>/table/<i>.bin). */
export function brdfTexture(buffer, meta) {
  const depth = meta.axes * meta.classes * meta.gradations;
  const texture = new THREE.Data3DTexture(
    singles(buffer), meta.slopeSteps, meta.thetaSteps, depth);
  texture.type = THREE.FloatType;
  texture.format = THREE.RGBAFormat;
  texture.minFilter = texture.magFilter = THREE.LinearFilter;
  texture.wrapS = texture.wrapT = texture.wrapR = THREE.ClampToEdgeWrapping;
  texture.unpackAlignment = 1;
  texture.needsUpdate = true;
  return texture;
}

const blank = new THREE.DataTexture(new Uint8Array([255, 255, 255, 255]), 1, 1);
blank.needsUpdate = true;

/** Shared uniforms: every material reads the sun and sky from here. */
export const lighting = {
  sunDirection: { value: new THREE.Vector3(0.42, 0, 0.91) },
  sunIrradiance: { value: new THREE.Vector3(Math.PI, Math.PI, Math.PI) },
  skyRadiance: { value: new THREE.Vector3(0.06, 0.08, 0.11) },
};

/** A feather material from its scene entry, its table texture and its map textures. */
export function featherMaterial(entry, table, maps, instanced) {
  const meta = entry.tableMeta;
  const defines = { FEATHER: 1 };
  if (instanced) defines.INSTANCED = 1;
  if (meta.axes === 1) defines.SHARED_AXES = 1;
  return new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3,
    vertexShader: VERTEX,
    fragmentShader: FRAGMENT,
    defines,
    side: THREE.DoubleSide,
    transparent: true,
    uniforms: {
      ...lighting,
      baseColor: { value: new THREE.Vector3() },
      brdf: { value: table },
      ocellarMap: { value: maps.ocellar ? ocellarTexture(maps.ocellar) : blank },
      packedMaps: { value: maps.packed },
      albedoMap: { value: maps.albedo },
      albedoSteps: { value: meta.albedoSteps },
      classes: { value: meta.classes },
      gradations: { value: meta.gradations },
      thetaSteps: { value: meta.thetaSteps },
      slopeSteps: { value: meta.slopeSteps },
      layers: { value: meta.axes * meta.classes * meta.gradations },
      slopeMax: { value: meta.slopeMax },
      alphaXG: { value: meta.alphaXG },
      alphaY: { value: meta.alphaY },
      melaninRgb: { value: new THREE.Vector3(...meta.melaninRgb) },
    },
  });
}

/** A Lambertian material of a UsdPreviewSurface's diffuse colour. */
export function previewMaterial(entry, instanced) {
  return new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3,
    vertexShader: VERTEX,
    fragmentShader: FRAGMENT,
    defines: instanced ? { INSTANCED: 1 } : {},
    side: THREE.DoubleSide,
    uniforms: { ...lighting, baseColor: { value: new THREE.Vector3(...entry.color) } },
  });
}
