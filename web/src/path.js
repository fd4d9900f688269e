// The path: its control points as handles to drag (TransformControls), the curve through them, and
// the sketch mode (FM: "specify the global path by sketching an arbitrary curve"): a freehand
// stroke on a plane through both shapes, facing the camera, resampled by arc length to points.
// In a shot with a group picked, the path is that group's: between its own shapes, through its own
// points (else the top level's, which it flies), and an edit gives the group its own points.
import * as THREE from 'three';
import { TransformControls } from 'three/examples/jsm/controls/TransformControls.js';

const HANDLE_COLOUR = 0xffd23f, CURVE_COLOUR = 0xff5fd2;

export class PathEditor {
  constructor(view, onEdit) {
    this.view = view;
    this.onEdit = onEdit; // (points) => the page sends set path.points
    this.points = [];
    this.editGroup = -1; // a shot's group whose path is edited (-1: the top level)
    this.ends = [new THREE.Vector3(), new THREE.Vector3()];
    this.curveKind = 'polyline';
    this.group = new THREE.Group();
    view.scene.add(this.group);
    this.line = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: CURVE_COLOUR }));
    this.line.frustumCulled = false;
    view.scene.add(this.line);
    this.gizmo = new TransformControls(view.camera, view.renderer.domElement);
    this.gizmo.addEventListener('dragging-changed', (e) => this.dragChanged(e.value));
    this.gizmo.addEventListener('objectChange', () => this.drawCurve());
    this.gizmo.addEventListener('change', () => { view.dirty = true; });
    view.scene.add(this.gizmo.getHelper());
    this.sketching = false;
    this.stroke = null;
    this.sketchPoints = 4;
    const dom = view.renderer.domElement;
    dom.addEventListener('pointerdown', (e) => this.pointerDown(e));
    dom.addEventListener('pointermove', (e) => this.pointerMove(e));
    dom.addEventListener('pointerup', (e) => this.pointerUp(e));
  }

  // The scene's control points and the shapes' centres as the ends (C_S, C_T: drawn, not edited).
  setScene(doc, shapes) {
    const path = groupPath(doc, this.editGroup);
    this.curveKind = path.curve ?? 'polyline';
    for (const s of groupShapes(doc, shapes, this.editGroup)) {
      const end = s.name === 'source' ? this.ends[0] : s.name === 'target' ? this.ends[1] : null;
      if (end) end.copy(vertexMean(s.vertices));
    }
    if (this.gizmo.dragging) return; // the page's own drag wins until it ends
    this.points = (path.points ?? []).map((p) => new THREE.Vector3(...p));
    this.makeHandles();
    this.drawCurve();
  }

  handleRadius() {
    return Math.max(0.15, this.ends[0].distanceTo(this.ends[1]) / 40);
  }

  makeHandles() {
    const selected = this.gizmo.object ? this.group.children.indexOf(this.gizmo.object) : -1;
    this.gizmo.detach();
    for (const h of [...this.group.children]) { h.geometry.dispose(); this.group.remove(h); }
    const geometry = new THREE.SphereGeometry(this.handleRadius(), 16, 12);
    this.points.forEach((p, i) => {
      const h = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ color: HANDLE_COLOUR }));
      h.position.copy(p);
      h.userData.index = i;
      this.group.add(h);
    });
    if (selected >= 0 && selected < this.group.children.length) this.gizmo.attach(this.group.children[selected]);
  }

  // The curve through C_S, the handles and C_T (Catmull-Rom where the scene asks for it).
  drawCurve() {
    const through = [this.ends[0], ...this.group.children.map((h) => h.position), this.ends[1]];
    const pts = this.curveKind === 'catmull_rom' && through.length > 2
      ? new THREE.CatmullRomCurve3(through, false, 'catmullrom', 0.5).getPoints(24 * through.length) : through;
    this.setLine(pts);
  }

  // A new geometry each time: setFromPoints keeps an existing buffer's length.
  setLine(points) {
    this.line.geometry.dispose();
    this.line.geometry = new THREE.BufferGeometry().setFromPoints(points);
    this.view.dirty = true;
  }

  dragChanged(dragging) {
    this.view.orbit.enabled = !dragging;
    if (!dragging) this.onEdit(this.group.children.map((h) => h.position.toArray().map(round)));
  }

  select(i) {
    const h = this.group.children[i];
    if (h) this.gizmo.attach(h); else this.gizmo.detach();
  }

  // Where a point of the scene is on the page, in CSS pixels (tests press the mouse there).
  onScreen(x, y, z) {
    const v = new THREE.Vector3(x, y, z).project(this.view.camera), r = this.view.renderer.domElement.getBoundingClientRect();
    return { x: r.left + (v.x + 1) / 2 * r.width, y: r.top + (1 - v.y) / 2 * r.height };
  }

  handleOnScreen(i) {
    const h = this.group.children[i];
    return h ? this.onScreen(h.position.x, h.position.y, h.position.z) : null;
  }

  endsOnScreen() { return this.ends.map((e) => this.onScreen(e.x, e.y, e.z)); }

  // The ray through the pointer.
  ray(e) {
    const r = this.view.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
    const caster = new THREE.Raycaster();
    caster.setFromCamera(ndc, this.view.camera);
    return caster;
  }

  pointerDown(e) {
    if (this.sketching) {
      this.stroke = [];
      this.view.renderer.domElement.setPointerCapture(e.pointerId);
      this.pointerMove(e);
      return;
    }
    if (this.gizmo.dragging || this.gizmo.axis) return; // the gizmo takes it
    this.group.updateMatrixWorld(); // handles made since the last draw (another group picked) are placed
    const hit = this.ray(e).intersectObjects(this.group.children)[0];
    if (hit) this.gizmo.attach(hit.object);
  }

  pointerMove(e) {
    if (!this.stroke) return;
    const p = this.ray(e).ray.intersectPlane(this.sketchPlane(), new THREE.Vector3());
    if (p) this.stroke.push(p);
    this.setLine([this.ends[0], ...this.stroke, this.ends[1]]);
  }

  pointerUp() {
    if (!this.stroke) return;
    const stroke = this.stroke;
    this.stroke = null;
    if (stroke.length < 2) return this.drawCurve();
    this.points = resample(stroke, this.sketchPoints);
    this.makeHandles();
    this.drawCurve();
    this.onEdit(this.points.map((p) => p.toArray().map(round)));
  }

  // Through the middle of C_S and C_T, containing the line between them, turned to the camera.
  sketchPlane() {
    const d = this.ends[1].clone().sub(this.ends[0]).normalize();
    const view = this.view.camera.getWorldDirection(new THREE.Vector3());
    const n = view.sub(d.clone().multiplyScalar(view.dot(d)));
    if (n.lengthSq() < 1e-9) n.set(0, 0, 1);
    const mid = this.ends[0].clone().add(this.ends[1]).multiplyScalar(0.5);
    return new THREE.Plane().setFromNormalAndCoplanarPoint(n.normalize(), mid);
  }

  setSketching(on) {
    this.sketching = on;
    this.view.orbit.enabled = !on;
    this.gizmo.detach();
    this.view.container.classList.toggle('sketching', on);
  }
}

// A group's path: its own path keys over the top level's, key by key, as the loader lays them.
export function groupPath(doc, group) {
  const own = group >= 0 ? doc.groups?.[group]?.path : undefined;
  return { ...(doc.path ?? {}), ...(own ?? {}) };
}

// The shapes a group flies between (every shape for the top level): its own (the shapes message
// names each shape's group), and for a group from another's formed shape that group's target as
// its source.
export function groupShapes(doc, shapes, group) {
  if (group < 0) return shapes;
  const from = doc.groups?.[group]?.source?.group, k = doc.groups?.findIndex((g) => g.name === from) ?? -1;
  const formed = k >= 0 ? shapes.filter((s) => s.group === k && s.name === 'target').map((s) => ({ ...s, name: 'source' })) : [];
  return [...formed, ...shapes.filter((s) => s.group === group && !(k >= 0 && s.name === 'source'))];
}

// Scene units to a thousandth: the saved file stays readable, and the page and the file agree.
function round(x) { return Math.round(x * 1000) / 1000; }

function vertexMean(v) {
  const m = new THREE.Vector3();
  for (let i = 0; i < v.length; i += 3) m.x += v[i], m.y += v[i + 1], m.z += v[i + 2];
  return m.multiplyScalar(3 / Math.max(3, v.length));
}

// k points at equal arc length strictly inside the stroke (its ends are the shapes' centres).
export function resample(stroke, k) {
  const acc = [0];
  for (let i = 1; i < stroke.length; i++) acc.push(acc[i - 1] + stroke[i].distanceTo(stroke[i - 1]));
  const total = acc[acc.length - 1], out = [];
  for (let j = 1, i = 1; j <= k; j++) {
    const s = (total * j) / (k + 1);
    while (i < stroke.length - 1 && acc[i] < s) i++;
    const t = (s - acc[i - 1]) / Math.max(1e-12, acc[i] - acc[i - 1]);
    out.push(stroke[i - 1].clone().lerp(stroke[i], Math.min(1, Math.max(0, t))));
  }
  return out;
}
