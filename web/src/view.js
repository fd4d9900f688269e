// The scene and camera: the source, target and obstacle shapes, and the flock, drawn straight
// from a frame's typed arrays (tets as four triangles each, points as round sprites).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { ATTR } from './protocol.js';

// fm_phase: waiting, flying, homing, arrived (a shape flock's phases share the palette).
const PHASE_COLOURS = [0x8a8f99, 0x3fa7ff, 0xffa63f, 0x5fd35f].map((c) => new THREE.Color(c));
const SHAPE_COLOURS = { source: 0x6d7380, target: 0x9aa3b5, obstacle: 0xb05050 };
// Four faces of a tet from its vertices 0..3 (the cache's order).
const TET_FACES = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

export class View {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: false });
    this.renderer.setPixelRatio(window.devicePixelRatio);
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
    this.colourBy = 'phase';
    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    const w = this.container.clientWidth || 1, h = this.container.clientHeight || 1;
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
    if (this.flock && this.flock.userData.kind === kind && this.flock.userData.agents === agents) return this.flock;
    if (this.flock) { this.scene.remove(this.flock); this.flock.geometry.dispose(); }
    this.flock = kind === 'tets' ? makeTets(agents) : makePoints(agents);
    this.flock.userData = { kind, agents };
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
    colour(flock.geometry.getAttribute('color'), frame, previous, this.colourBy, tets ? 4 : 1);
    this.dirty = true;
  }

  render() {
    if (!this.dirty) return;
    this.dirty = false;
    this.renderer.render(this.scene, this.camera);
  }
}

function makeTets(agents) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(agents * 12), 3));
  g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(agents * 12), 3));
  const index = new Uint32Array(agents * 12);
  for (let a = 0; a < agents; a++) for (let i = 0; i < 12; i++) index[12 * a + i] = 4 * a + TET_FACES[i];
  g.setIndex(new THREE.BufferAttribute(index, 1));
  const material = new THREE.MeshLambertMaterial({ vertexColors: true, flatShading: true, side: THREE.DoubleSide });
  return new THREE.Mesh(g, material);
}

function makePoints(agents) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(agents * 3), 3));
  g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(agents * 3), 3));
  const material = new THREE.PointsMaterial({ size: 0.45, vertexColors: true, map: discSprite(), alphaTest: 0.5,
    sizeAttenuation: true });
  return new THREE.Points(g, material);
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
    for (let r = 0, at = 3 * repeat * a; r < repeat; r++, at += 3) { out[at] = _c.r; out[at + 1] = _c.g; out[at + 2] = _c.b; }
  }
  attr.needsUpdate = true;
}

// Speeds scaled to 0..1 by the frame's largest.
function speeds(frame, previous) {
  const n = frame.agents, out = new Float32Array(n);
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
