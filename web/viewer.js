// Tree from Video's web viewer (issue 33): plays a game export's GLB two ways.
//   mode=skin     three.js skins the GLB and plays its animation (AnimationMixer)
//   mode=texture  the same meshes driven by bone_anim.exr in a vertex shader: per vertex
//                 x = h_k + t_k + q_k (p - h_k) over its joints (bone_anim.json's encoding); the
//                 leaf flap (morph targets) plays the GLB's weights in both modes
// URL parameters: glb (default tree.glb), bones (bone_anim.json), mode, lod (0), frame (a still
// frame for checks; else it plays), size (canvas pixels; else the window), ortho=cx,cy,half (an
// orthographic front camera: centre and half height in metres, glTF axes; else a perspective view
// framing the tree). window.viewer.render(frame, mode) renders a still and resolves when drawn.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

const params = new URLSearchParams(location.search);
const glbUrl = params.get('glb') || 'tree.glb';
const bonesUrl = params.get('bones') || 'bone_anim.json';
const size = Number(params.get('size') || 0);
const status = document.getElementById('status');
const say = (text) => { if (status) status.textContent = text; };

const renderer = new THREE.WebGLRenderer({ antialias: false, alpha: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(size || innerWidth, size || innerHeight);
renderer.setClearColor(0x000000, 0);
document.body.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.add(new THREE.HemisphereLight(0xffffff, 0x445544, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 2.0);
sun.position.set(3, 10, 6);
scene.add(sun);

let camera;
const ortho = params.get('ortho') === 'persp' ? null : params.get('ortho');

function frameCamera(box) {
  const aspect = (size || innerWidth) / (size || innerHeight);
  if (ortho) {
    const [cx, cy, half] = ortho.split(',').map(Number);
    camera = new THREE.OrthographicCamera(cx - half * aspect, cx + half * aspect, cy + half, cy - half, 0.01, 1000);
    camera.position.set(0, 0, 100);                 // the front: looking down glTF's -Z (Blender's +Y)
    camera.lookAt(0, 0, 0);
    camera.position.set(0, 0, 100);
    return;
  }
  const c = box.getCenter(new THREE.Vector3());
  const h = box.getSize(new THREE.Vector3()).y;
  camera = new THREE.PerspectiveCamera(35, aspect, 0.05, 500);
  camera.position.set(c.x, c.y, c.z + 1.9 * h);
  camera.lookAt(c);
}

// --- bone texture mode: each skinned primitive becomes a plain mesh whose vertex shader skins it
function textureMaterial(base, anim, jointToBone) {
  const mat = base.clone();
  mat.onBeforeCompile = (shader) => {
    shader.uniforms.boneAnim = { value: anim.texture };
    shader.uniforms.boneHeads = { value: anim.heads };
    shader.uniforms.jointToBone = { value: jointToBone };
    shader.uniforms.animRow = anim.row;
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', `#include <common>
        uniform sampler2D boneAnim;
        uniform sampler2D boneHeads;
        uniform sampler2D jointToBone;
        uniform int animRow;
        attribute vec4 skinIndex;
        attribute vec4 skinWeight;
        vec3 quatRotate(vec4 q, vec3 v) { return v + 2.0 * cross(q.xyz, cross(q.xyz, v) + q.w * v); }
        int boneOf(float joint) { return int(texelFetch(jointToBone, ivec2(int(joint), 0), 0).r); }
        vec3 playPoint(int k, vec3 p) {
          vec3 h = texelFetch(boneHeads, ivec2(k, 0), 0).xyz;
          vec3 t = texelFetch(boneAnim, ivec2(2 * k, animRow), 0).xyz;
          vec4 q = normalize(texelFetch(boneAnim, ivec2(2 * k + 1, animRow), 0));
          return h + t + quatRotate(q, p - h);
        }
        vec3 playNormal(int k, vec3 n) {
          vec4 q = normalize(texelFetch(boneAnim, ivec2(2 * k + 1, animRow), 0));
          return quatRotate(q, n);
        }`)
      .replace('#include <skinnormal_vertex>', `#include <skinnormal_vertex>
        {
          vec3 nrm = vec3(0.0);
          for (int i = 0; i < 4; i++) { if (skinWeight[i] > 0.0) nrm += skinWeight[i] * playNormal(boneOf(skinIndex[i]), objectNormal); }
          objectNormal = normalize(nrm);
        }`)
      .replace('#include <skinning_vertex>', `#include <skinning_vertex>
        {
          vec3 bind = transformed;                 // the bind pose, morphed (the leaf flap)
          vec3 played = vec3(0.0);
          for (int i = 0; i < 4; i++) { if (skinWeight[i] > 0.0) played += skinWeight[i] * playPoint(boneOf(skinIndex[i]), bind); }
          transformed = played;
        }`);
  };
  mat.customProgramCacheKey = () => 'bone-texture';
  return mat;
}

async function loadBoneTexture() {
  const doc = await (await fetch(bonesUrl)).json();
  const texture = await new EXRLoader().setDataType(THREE.FloatType).loadAsync(doc.image ? new URL(doc.image, new URL(bonesUrl, location.href)).href : 'bone_anim.exr');
  texture.minFilter = texture.magFilter = THREE.NearestFilter;
  texture.generateMipmaps = false;
  texture.needsUpdate = true;
  const K = doc.bones.length;
  const heads = new Float32Array(4 * K);
  doc.bind_heads.forEach((h, k) => heads.set([h[0], h[1], h[2], 1], 4 * k));
  const headTex = new THREE.DataTexture(heads, K, 1, THREE.RGBAFormat, THREE.FloatType);
  headTex.needsUpdate = true;
  return { doc, texture, heads: headTex, row: { value: 0 } };
}

const state = { mode: params.get('mode') || 'skin', lod: Number(params.get('lod') || 0) };
let gltf, mixer, action, anim, fps = 30, frames = 1;
const skinned = [], plain = [];

function showMode() {
  const lodOk = (name) => !/_LOD\d+$/.test(name) || name.endsWith(`_LOD${state.lod}`);
  for (const m of skinned) m.visible = state.mode === 'skin' && lodOk(m.userData.lodName);
  for (const m of plain) m.visible = state.mode === 'texture' && lodOk(m.userData.lodName);
}

function setFrame(frame) {
  if (mixer) { mixer.setTime(frame / fps); }
  if (anim) {
    const F = anim.doc.frame_count;
    const f = ((Math.round(frame) % F) + F) % F;
    anim.row.value = F - 1 - f;                     // EXRLoader puts the image's top row last
  }
}

async function start() {
  say('loading ' + glbUrl);
  gltf = await new GLTFLoader().loadAsync(glbUrl);
  scene.add(gltf.scene);
  gltf.scene.traverse((o) => {
    if (o.isSkinnedMesh) {
      const owner = o.parent && /_LOD\d+$/.test(o.parent.name) ? o.parent.name : o.name;
      o.userData.lodName = owner;
      o.frustumCulled = false;
      skinned.push(o);
    }
  });
  const clip = gltf.animations[0];
  if (clip) {
    mixer = new THREE.AnimationMixer(gltf.scene);
    action = mixer.clipAction(clip);
    action.play();
  }
  try {
    anim = await loadBoneTexture();
    fps = anim.doc.fps;
    frames = anim.doc.frame_count;
    for (const s of skinned) {
      const jointNames = s.skeleton.bones.map((b) => b.name);
      const map = new Float32Array(4 * jointNames.length);
      jointNames.forEach((n, j) => { map[4 * j] = anim.doc.bones.indexOf(n); });
      const jt = new THREE.DataTexture(map, jointNames.length, 1, THREE.RGBAFormat, THREE.FloatType);
      jt.needsUpdate = true;
      const m = new THREE.Mesh(s.geometry, textureMaterial(s.material, anim, jt));
      // the leaf flap is morph targets, not bones: both modes play the GLB's weights (the morph
      // first, then the bone texture's skinning, where three's skinning chunk sits)
      if (s.morphTargetInfluences) { m.morphTargetInfluences = s.morphTargetInfluences; m.morphTargetDictionary = s.morphTargetDictionary; }
      m.userData.lodName = s.userData.lodName;
      m.frustumCulled = false;
      scene.add(m);
      plain.push(m);
    }
  } catch (err) {
    console.warn('no bone texture:', err);
    if (state.mode === 'texture') throw err;
  }
  if (clip && !anim) { fps = 30; frames = Math.round(clip.duration * fps) + 1; }
  const box = new THREE.Box3();
  for (const s of skinned) { s.geometry.computeBoundingBox(); box.union(s.geometry.boundingBox); }
  frameCamera(box);
  showMode();
  say(`${skinned.length} skinned primitives, ${clip ? clip.name : 'no animation'}, ${frames} frames at ${fps} fps`);
}

window.viewer = {
  ready: null,
  async render(frame, mode) {
    await window.viewer.ready;
    if (mode) { state.mode = mode; showMode(); }
    setFrame(frame);
    gltf.scene.updateMatrixWorld(true);
    renderer.render(scene, camera);
    const gl = renderer.getContext();
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    return { renderer: info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER),
             png: renderer.domElement.toDataURL('image/png') };
  },
};
window.viewer.ready = start().catch((err) => { say('error: ' + err.message); throw err; });

if (!params.has('frame')) {
  const clock = new THREE.Clock();
  window.viewer.ready.then(() => {
    renderer.setAnimationLoop(() => {
      const t = clock.getElapsedTime();
      setFrame((t * fps) % frames);
      renderer.render(scene, camera);
    });
  });
  addEventListener('keydown', (e) => {
    if (e.key === 'm') { state.mode = state.mode === 'skin' ? 'texture' : 'skin'; showMode(); }
    if (/^[0-9]$/.test(e.key)) { state.lod = Number(e.key); showMode(); }
  });
  addEventListener('resize', () => { renderer.setSize(innerWidth, innerHeight); });
}
