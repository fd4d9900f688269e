// The scene and camera: the source, target and obstacle shapes, and the flock, drawn straight
// from a frame's typed arrays (tets as four triangles each, points as round sprites).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { ATTR } from './protocol.js';
import { DynamicResolution } from './resolution.js';
import { TET_FACES, frontFaces, restingTets, sharedFaces } from './tets.js';

// fm_phase: waiting, flying, homing, arrived (a shape flock's phases share the palette).
const PHASE_COLOURS = [0x8a8f99, 0x3fa7ff, 0xffa63f, 0x5fd35f].map((c) => new THREE.Color(c));
const SHAPE_COLOURS = { source: 0x6d7380, target: 0x9aa3b5, obstacle: 0xb05050 };

// How the tets are drawn (docs/studio.md, "Frame rate"). 'flat': each face its colour times one
// light term from the face's own normal (screen-space derivatives), no three.js lights; cull: only
// the faces that face the eye, chosen on the CPU each frame (tets.js): a closed tet shows only
// those, so the eye cannot tell, and the rasterizer sets up half the triangles; tiny: a tet under
// this many pixels is drawn as its one face that faces the eye most (a quarter); rest: the tets at
// rest in the source (as in the run's first frame) or the target (as in its last) leave out the
// faces they share, which the tets hide themselves (tets.js: the shapes are drawn as their surface,
// the same picture with a fifth of words' triangles at its start and end); wide: 32-bit indices even
// where 16 bits hold every vertex (a flock of at most 16,384 tets: half the index buffer's upload).
// 'lambert': three.js's lit material, every face on both sides, as the studio drew them first, and
// 'plain' the drawing before rest and 16-bit indices (kept for the benchmark's before and after).
export const TET_STYLES = {
  flat: { material: 'flat', cull: true, tiny: 3, rest: true },
  plain: { material: 'flat', cull: true, tiny: 3, wide: true },
  lambert: { material: 'lambert', cull: false, wide: true },
};

export class View {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: false, powerPreference: 'high-performance' });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    this.resolution = new DynamicResolution();
    this.dynamicResolution = true; // off: always the device's pixel ratio (the benchmark's before)
    this.tetStyle = TET_STYLES.flat;
    this.pointStyle = 'disc'; // 'sprite': three.js's PointsMaterial with a disc texture (the first drawing)
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x15171c);
    THREE.Object3D.DEFAULT_UP.set(0, 0, 1); // the engine's scenes are Z-up (scene.md, `up`)
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.05, 5000);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(0, -60, 30);
    this.orbit = new OrbitControls(this.camera, this.renderer.domElement);
    // Drawn only when something changed: a still page costs no CPU (SwiftShader, laptops).
    this.dirty = true;
    this.orbit.addEventListener('change', () => { this.dirty = true; });
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.2);
    sun.position.set(20, -30, 50);
    this.scene.add(sun);
    this.shapes = new THREE.Group();
    this.scene.add(this.shapes);
    this.flock = null;
    this.restShapes = [null, null]; // the source's and the target's tets at rest: {v, across} (setRestShape)
    this.restTags = ['', ''];
    this.restVersion = 0;
    this.colourBy = 'phase';
    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    const w = this.container.clientWidth || 1, h = this.container.clientHeight || 1;
    this.renderer.setPixelRatio(window.devicePixelRatio * this.resolution.ratio);
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.dirty = true;
  }

  setShapes(list) {
    for (const m of [...this.shapes.children]) { m.geometry.dispose(); this.shapes.remove(m); }
    for (const s of list) {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.Float32BufferAttribute(s.vertices, 3));
      g.setIndex(s.triangles);
      const material = new THREE.MeshBasicMaterial({ color: SHAPE_COLOURS[s.name] ?? 0x888888, wireframe: true,
        transparent: true, opacity: s.name === 'obstacle' ? 0.5 : 0.18 });
      const mesh = new THREE.Mesh(g, material);
      mesh.name = s.name;
      this.shapes.add(mesh);
    }
    this.dirty = true;
  }

  // Frames the camera on the shapes (once, when the first ones come).
  frameShapes() { this.frameBox(new THREE.Box3().setFromObject(this.shapes)); }

  // ... or, with no shapes (a played cache), on frames' positions (the first and the last: where
  // the flock starts and where it ends).
  framePositions(arrays) {
    const box = new THREE.Box3();
    for (const p of arrays) for (let i = 0; i < p.length; i += 3) box.expandByPoint(_v.set(p[i], p[i + 1], p[i + 2]));
    this.frameBox(box);
  }

  frameBox(box) {
    if (box.isEmpty()) return;
    this.framed = true;
    const centre = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3()).length();
    this.orbit.target.copy(centre);
    this.camera.position.copy(centre).add(new THREE.Vector3(0, -0.9 * size, 0.45 * size));
    this.camera.near = size / 500;
    this.camera.far = size * 50;
    this.camera.updateProjectionMatrix();
    this.orbit.update();
  }

  // The flock object for this many agents of this kind, made again only when they change.
  ensureFlock(kind, agents) {
    const u = this.flock?.userData, wide = !!this.tetStyle.wide;
    if (u && u.kind === kind && u.agents === agents && (kind !== 'tets' || u.wide === wide)) return this.flock;
    if (this.flock) { this.scene.remove(this.flock); this.flock.geometry.dispose(); this.flock.material.dispose(); }
    this.flock = kind === 'tets' ? makeTets(agents, this.tetStyle) : makePoints(agents, this.pointStyle);
    this.facesFor = null;
    this.flock.userData = { kind, agents, wide, resting: new Uint8Array(kind === 'tets' ? agents : 0) };
    this.flock.frustumCulled = false; // positions change every frame; no bounding sphere to keep
    this.scene.add(this.flock);
    return this.flock;
  }

  // Draws a frame: the positions copied into the flock's buffer, colours by the chosen attribute.
  showFrame(frame, previous) {
    const tets = frame.attrs[ATTR.TET_VERTICES];
    const positions = tets ?? frame.attrs[ATTR.POSITION];
    if (!positions) return;
    const flock = this.ensureFlock(tets ? 'tets' : 'points', frame.agents);
    const pos = flock.geometry.getAttribute('position');
    pos.array.set(positions);
    pos.needsUpdate = true;
    this.shownFrame = (this.shownFrame ?? 0) + 1; // the faces that face the eye are found again before the next draw
    colour(flock.geometry.getAttribute('color'), frame, previous, this.colourBy, tets ? 4 : 1);
    this.dirty = true;
  }

  // A shape the tets rest in (i: 0 the source, 1 the target), from a frame where they form it
  // (tag: which frame of which run, so that it is found once).
  setRestShape(i, frame, tag) {
    const v = frame.attrs[ATTR.TET_VERTICES];
    this.restTags[i] = tag;
    this.restShapes[i] = v ? { v, across: sharedFaces(v, frame.agents) } : null;
    this.restVersion += 1;
    this.facesFor = null;
    this.dirty = true;
  }

  // Only the faces that face the eye go to the index buffer (its used part uploaded), found again
  // when the flock or the camera moved; every face, once, without culling.
  cullFaces() {
    const flock = this.flock;
    if (flock?.userData.kind !== 'tets') return;
    const g = flock.geometry, index = g.index, eye = this.camera.position, style = this.tetStyle;
    const height = this.container.clientHeight || 1, agents = flock.userData.agents;
    const key = style.cull ? `${this.shownFrame},${eye.x},${eye.y},${eye.z},${height},${this.restVersion}` : 'all';
    if (this.facesFor === key) return;
    const perUnit = height / 2 / Math.tan((this.camera.fov * Math.PI) / 360); // a unit at distance 1, in CSS pixels
    const v = g.getAttribute('position').array;
    const rest = style.rest && this.restShapes.some(Boolean) ? restingTets(v, agents, this.restShapes, flock.userData.resting) : null;
    const count = style.cull
      ? frontFaces(v, agents, eye, index.array, perUnit, style.tiny ?? 0, rest)
      : fillAllFaces(index.array, agents);
    this.facesFor = key;
    index.clearUpdateRanges();
    index.addUpdateRange(0, count);
    index.needsUpdate = true;
    g.setDrawRange(0, count);
  }

  // The tets' drawing (TET_STYLES).
  setTetStyle(style) {
    this.tetStyle = style;
    this.facesFor = null;
    if (this.flock?.userData.kind !== 'tets') return;
    if (this.flock.userData.wide !== !!style.wide) { // another index width: the flock is made again
      const { agents } = this.flock.userData, positions = this.flock.geometry.getAttribute('position').array;
      const colours = this.flock.geometry.getAttribute('color').array;
      this.ensureFlock('tets', agents);
      this.flock.geometry.getAttribute('position').array.set(positions);
      this.flock.geometry.getAttribute('color').array.set(colours);
    }
    this.flock.material.dispose();
    this.flock.material = tetMaterial(style);
    this.dirty = true;
  }

  // The points' drawing: 'disc' (pointMaterial) or 'sprite' (the first drawing, for the benchmark).
  setPointStyle(style) {
    this.pointStyle = style;
    if (this.flock?.userData.kind !== 'points') return;
    this.flock.material.dispose();
    this.flock.material = pointMaterial(style);
    this.dirty = true;
  }

  // Draws if something changed. playing: the timeline runs (the dynamic resolution applies); rate:
  // the frames per second it plays at (the budget); shown: the frames a second it shows.
  // The cost of a drawn frame is the time from its draw to the next animation frame (the browser's
  // raster of it included). Paused, the canvas goes back to full resolution and is drawn again.
  render(playing = false, rate = 24, shown = Infinity) {
    const now = performance.now(), r = this.resolution;
    if (!playing || !this.dynamicResolution) { if (r.full()) this.resize(); }
    else if (this.drawnAt !== undefined && r.measure(now - this.drawnAt, now, rate, shown)) this.resize();
    this.drawnAt = undefined;
    if (!this.dirty) return;
    this.dirty = false;
    this.cullFaces();
    this.renderer.render(this.scene, this.camera);
    this.drawnAt = now;
  }
}

// One vertex colour times 0.4 to 1 of a light over the viewer's left shoulder, by the face's normal
// from the screen-space derivatives of the view position (a flat face: one normal).
const FLAT_VERTEX = `
varying vec3 vColour;
varying vec3 vView;
void main() {
  vColour = color;
  vec4 mv = modelViewMatrix * vec4(position, 1.0);
  vView = mv.xyz;
  gl_Position = projectionMatrix * mv;
}`;
const FLAT_FRAGMENT = `
varying vec3 vColour;
varying vec3 vView;
void main() {
  vec3 n = normalize(cross(dFdx(vView), dFdy(vView)));
  float light = 0.4 + 0.6 * abs(dot(n, vec3(-0.36, 0.48, 0.8)));
  gl_FragColor = vec4(vColour * light, 1.0);
  #include <colorspace_fragment>
}`;

function tetMaterial(style) {
  const side = style.cull ? THREE.FrontSide : THREE.DoubleSide; // culled: the front faces, as the CPU chose them
  if (style.material === 'lambert') return new THREE.MeshLambertMaterial({ vertexColors: true, flatShading: true, side });
  return new THREE.ShaderMaterial({ vertexShader: FLAT_VERTEX, fragmentShader: FLAT_FRAGMENT, vertexColors: true, side });
}

// Colours as bytes (a quarter of float's upload each frame; clamped: assignment rounds), written in
// place: no buffer is made again while a run plays.
function colourAttribute(count) {
  return new THREE.BufferAttribute(new Uint8ClampedArray(count * 3), 3, true);
}

function makeTets(agents, style) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(agents * 12), 3));
  g.setAttribute('color', colourAttribute(agents * 4));
  const Index = !style.wide && agents * 4 <= 65536 ? Uint16Array : Uint32Array; // 4 vertices a tet
  const index = new THREE.BufferAttribute(new Index(agents * 12), 1);
  index.setUsage(THREE.DynamicDrawUsage);
  fillAllFaces(index.array, agents);
  g.setIndex(index);
  return new THREE.Mesh(g, tetMaterial(style));
}

function fillAllFaces(index, agents) {
  for (let a = 0; a < agents; a++) for (let i = 0; i < 12; i++) index[12 * a + i] = 4 * a + TET_FACES[i];
  return 12 * agents;
}

// A point flock's agents as round dots of `POINT_SIZE` scene units, smaller with the distance as
// three.js's PointsMaterial draws them (sizeAttenuation). The disc is cut from the point's square in
// the fragment shader: no texture, so no filtered lookup per pixel, which is most of a software
// rasterizer's (SwiftShader's) time for 10^5 points.
const POINT_SIZE = 0.45;
const POINT_VERTEX = `
uniform float size;
uniform float scale;
varying vec3 vColour;
void main() {
  vColour = color;
  vec4 mv = modelViewMatrix * vec4(position, 1.0);
  gl_PointSize = size * scale / -mv.z;
  gl_Position = projectionMatrix * mv;
}`;
const POINT_FRAGMENT = `
varying vec3 vColour;
void main() {
  vec2 c = gl_PointCoord - 0.5;
  if (dot(c, c) > 0.235) discard; /* as large as the sprite's disc (15 of 32 texels, filtered) */
  gl_FragColor = vec4(vColour, 1.0);
  #include <colorspace_fragment>
}`;

function pointMaterial(style) {
  if (style === 'sprite') {
    return new THREE.PointsMaterial({ size: POINT_SIZE, vertexColors: true, map: discSprite(), alphaTest: 0.5,
      sizeAttenuation: true });
  }
  return new THREE.ShaderMaterial({ vertexShader: POINT_VERTEX, fragmentShader: POINT_FRAGMENT, vertexColors: true,
    uniforms: { size: { value: POINT_SIZE }, scale: { value: 1 } } });
}

const _buffer = new THREE.Vector2();

function makePoints(agents, style) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(agents * 3), 3));
  g.setAttribute('color', colourAttribute(agents));
  const points = new THREE.Points(g, pointMaterial(style));
  // half the drawing buffer's height in pixels: PointsMaterial's scale (pixel ratio included)
  points.onBeforeRender = (renderer) => {
    const u = points.material.uniforms;
    if (u?.scale) u.scale.value = renderer.getDrawingBufferSize(_buffer).y * 0.5;
  };
  return points;
}

function discSprite() {
  const c = document.createElement('canvas');
  c.width = c.height = 32;
  const x = c.getContext('2d');
  x.fillStyle = '#fff';
  x.beginPath(); x.arc(16, 16, 15, 0, 2 * Math.PI); x.fill();
  return new THREE.CanvasTexture(c);
}

const _c = new THREE.Color();
const _v = new THREE.Vector3();

// Each agent's colour by phase, group, id or speed (the displacement since the previous frame, or
// a point flock's velocity), written to its `repeat` vertices.
function colour(attr, frame, previous, by, repeat) {
  const out = attr.array, n = frame.agents;
  const phase = frame.attrs[ATTR.PHASE], group = frame.attrs[ATTR.GROUP], id = frame.attrs[ATTR.ID];
  const speed = by === 'speed' ? speeds(frame, previous) : null;
  for (let a = 0; a < n; a++) {
    if (by === 'group' && group) _c.setHSL((group[a] * 0.618) % 1, 0.7, 0.55);
    else if (by === 'id') _c.setHSL(((id ? id[a] : a) / Math.max(1, n)) * 0.8, 0.75, 0.55);
    else if (speed) _c.setHSL(0.66 - 0.66 * speed[a], 0.85, 0.5);
    else _c.copy(PHASE_COLOURS[phase ? phase[a] & 3 : 1]);
    const r8 = 255 * _c.r, g8 = 255 * _c.g, b8 = 255 * _c.b;
    for (let r = 0, at = 3 * repeat * a; r < repeat; r++, at += 3) { out[at] = r8; out[at + 1] = g8; out[at + 2] = b8; }
  }
  attr.needsUpdate = true;
}

// Speeds scaled to 0..1 by the frame's largest (in one array kept for the next frame).
let _speeds = new Float32Array(0);
function speeds(frame, previous) {
  const n = frame.agents;
  if (_speeds.length < n) _speeds = new Float32Array(n);
  const out = _speeds;
  const vel = frame.attrs[ATTR.VELOCITY];
  const now = frame.attrs[ATTR.TET_VERTICES] ?? frame.attrs[ATTR.POSITION];
  const then = previous && (previous.attrs[ATTR.TET_VERTICES] ?? previous.attrs[ATTR.POSITION]);
  const stride = frame.attrs[ATTR.TET_VERTICES] ? 12 : 3;
  let top = 1e-9;
  for (let a = 0; a < n; a++) {
    let dx, dy, dz;
    if (vel) { dx = vel[3 * a]; dy = vel[3 * a + 1]; dz = vel[3 * a + 2]; }
    else if (then && then.length === now.length) {
      dx = now[stride * a] - then[stride * a]; dy = now[stride * a + 1] - then[stride * a + 1];
      dz = now[stride * a + 2] - then[stride * a + 2];
    } else { dx = dy = dz = 0; }
    out[a] = Math.hypot(dx, dy, dz);
    top = Math.max(top, out[a]);
  }
  for (let a = 0; a < n; a++) out[a] /= top;
  return out;
}
