// Unit tests of the page's pure parts, under node's own test runner (no browser):
//   node --test web/test/          (ctest: test_studio_page)
// protocol.js's frame parsing against the layout docs/studio.md gives, path.js's arc-length
// resampling of a sketch, panel.js's dotted keys, a shot's group keys and values and path.js's
// group path, resolution.js's dynamic resolution, tets.js's choice of the faces that face the eye.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import * as THREE from 'three';
import { ATTR, parseFrame } from '../src/protocol.js';
import { groupPath, groupShapes, resample } from '../src/path.js';
import { editable, getKey, groupNames, groupValue, scopedKey } from '../src/panel.js';
import { DynamicResolution, RATIOS } from '../src/resolution.js';
import { TET_FACES, frontFaces, restingTets, sharedFaces } from '../src/tets.js';

// A frame message as the server writes it (tools/studio_frames.c): header, entries, 16-aligned arrays.
function frameMessage(agents, arrays) {
  const align = (n) => Math.ceil(n / 16) * 16;
  let at = align(20 + 12 * arrays.length);
  const places = arrays.map(([, a]) => { const p = at; at = align(at + a.byteLength); return p; });
  const buf = new ArrayBuffer(at), dv = new DataView(buf);
  [..."FMF1"].forEach((c, i) => dv.setUint8(i, c.charCodeAt(0)));
  dv.setUint32(4, 3, true); dv.setUint32(8, 17, true); dv.setUint32(12, agents, true); dv.setUint32(16, arrays.length, true);
  arrays.forEach(([attr, a], i) => {
    dv.setUint32(20 + 12 * i, attr, true); dv.setUint32(24 + 12 * i, places[i], true); dv.setUint32(28 + 12 * i, a.byteLength, true);
    new Uint8Array(buf, places[i], a.byteLength).set(new Uint8Array(a.buffer, a.byteOffset, a.byteLength));
  });
  return buf;
}

test('parseFrame views each attribute in place', () => {
  const tets = Float32Array.from({ length: 24 }, (_, i) => i * 0.5), phase = Uint8Array.of(1, 3), ids = Uint32Array.of(7, 9);
  const f = parseFrame(frameMessage(2, [[ATTR.TET_VERTICES, tets], [ATTR.ID, ids], [ATTR.PHASE, phase]]));
  assert.equal(f.generation, 3); assert.equal(f.k, 17); assert.equal(f.agents, 2);
  assert.deepEqual(Array.from(f.attrs[ATTR.TET_VERTICES]), Array.from(tets));
  assert.deepEqual(Array.from(f.attrs[ATTR.ID]), [7, 9]);
  assert.deepEqual(Array.from(f.attrs[ATTR.PHASE]), [1, 3]);
  assert.equal(f.attrs[ATTR.TET_VERTICES].buffer, f.buffer); // a view, not a copy
});

test('parseFrame refuses what is not a frame', () => {
  assert.throws(() => parseFrame(new TextEncoder().encode('{"type": "status"}   ').buffer), /not a frame/);
});

test('resample puts k points at equal arc length inside the stroke', () => {
  const stroke = [0, 1, 2, 4, 10].map((x) => new THREE.Vector3(x, 0, 0)); // uneven samples of one line
  const pts = resample(stroke, 4);
  assert.deepEqual(pts.map((p) => Math.round(p.x * 1e6) / 1e6), [2, 4, 6, 8]);
  const bow = [new THREE.Vector3(0, 0, 0), new THREE.Vector3(0, 3, 0), new THREE.Vector3(4, 3, 0)]; // 3 then 4 long
  assert.deepEqual(resample(bow, 6).map((p) => [p.x, p.y].map((v) => Math.round(v * 1e6) / 1e6)),
    [[0, 1], [0, 2], [0, 3], [1, 3], [2, 3], [3, 3]]);
});

test('getKey reads dotted keys and tells a missing one', () => {
  const doc = { speed0: 8, path: { points: [[0, 1, 2]] }, shape_flock: { cohesion: { weight: [0.1, 0.2] } } };
  assert.equal(getKey(doc, 'speed0'), 8);
  assert.deepEqual(getKey(doc, 'shape_flock.cohesion.weight'), [0.1, 0.2]);
  assert.equal(getKey(doc, 'path.width'), undefined);
  assert.equal(getKey(doc, 'mde.d_min'), undefined);
});

// A shot as the loader reads it: group 1 sets its own speed0 and path points, group 2 starts from
// group 0's formed shape.
const SHOT = { speed0: 8, time: { frame_limit: 24 }, path: { points: [[0, 5, 0]], curve: 'catmull_rom' },
  style: { fields: [{ type: 'curl_noise', gain: 0.5 }] },
  groups: [{ name: 'a' }, { name: 'b', speed0: 5, path: { points: [[1, 2, 3], [4, 5, 6]] } },
    { name: 'c', source: { group: 'a' } }] };

test('a group edits its own keys and shows the top level\'s where it has none', () => {
  assert.equal(scopedKey(-1, 'speed0'), 'speed0');
  assert.equal(scopedKey(1, 'path.points'), 'groups.1.path.points');
  assert.equal(groupValue(SHOT, 1, 'speed0'), 5);
  assert.equal(groupValue(SHOT, 0, 'speed0'), 8); // the top level's, which group 0 flies with
  assert.equal(groupValue(SHOT, -1, 'speed0'), 8);
  assert.equal(groupValue(SHOT, 1, 'style.fields.0.gain'), 0.5);
  assert.equal(groupValue(SHOT, 2, 'mde.d_min'), undefined);
  assert.ok(editable(SHOT, 1, 'speed0') && editable(SHOT, 0, 'n') && editable(SHOT, -1, 'time.frame_limit'));
  assert.ok(!editable(SHOT, 1, 'time.frame_limit'), 'the whole shot shares time');
  assert.ok(!editable(SHOT, 2, 'n'), 'a group from another\'s shape has its agents');
});

test('the "Edit" list follows the groups a scene has now (the panel rebuilds it when these change)', () => {
  assert.deepEqual(groupNames(SHOT), ['a', 'b', 'c']);
  assert.deepEqual(groupNames({ ...SHOT, groups: SHOT.groups.slice(0, 2) }), ['a', 'b']);
  assert.deepEqual(groupNames({ speed0: 8 }), [], 'a scene without groups offers none');
  assert.deepEqual(groupNames({ groups: null }), []);
});

test('a group\'s path: its own keys over the top level\'s, between its own shapes', () => {
  assert.deepEqual(groupPath(SHOT, 1), { points: [[1, 2, 3], [4, 5, 6]], curve: 'catmull_rom' });
  assert.deepEqual(groupPath(SHOT, 0), SHOT.path);
  const shape = (name, group) => ({ name, group, vertices: [group, 0, 0] });
  const shapes = [shape('source', 0), shape('target', 0), shape('source', 1), shape('target', 1), shape('obstacle', 1),
    shape('target', 2)];
  assert.deepEqual(groupShapes(SHOT, shapes, 1).map((s) => `${s.name} ${s.group}`), ['source 1', 'target 1', 'obstacle 1']);
  assert.deepEqual(groupShapes(SHOT, shapes, 2).map((s) => `${s.name} ${s.group}`), ['source 0', 'target 2'],
    'a group from another\'s shape starts where that group formed it');
  assert.equal(groupShapes(SHOT, shapes, -1).length, shapes.length);
});

// Feeds frames of cost(ratio) ms, one every 50 ms of page time, and returns the ratios it chose.
function settle(cost, frames, rate = 24) {
  const d = new DynamicResolution(), seen = [];
  for (let i = 0, now = 0; i < frames; i++, now += 50) { d.measure(cost(d.ratio), now, rate); seen.push(d.ratio); }
  return { d, seen };
}

test('dynamic resolution steps down while frames cost more than the frame rate allows', () => {
  // a software rasterizer's frame: 12 ms of fixed work and 60 ms of pixels at full resolution
  const { d, seen } = settle((r) => 12 + 60 * r * r, 200);
  assert.equal(d.ratio, 0.5); // 12 + 15 = 27 ms < 37.5 ms (24 frames/s with a 10 % margin); 0.75: 45.75 ms
  assert.ok(seen.indexOf(0.75) < seen.indexOf(0.5), 'through 0.75 first');
  assert.equal(new Set(seen.slice(100)).size, 1, 'and stays there: no see-saw');
});

test('dynamic resolution stays at full resolution under budget and goes back up when frames get cheap', () => {
  assert.deepEqual(new Set(settle(() => 20, 100).seen), new Set([1]));
  const d = new DynamicResolution();
  for (let i = 0, now = 0; i < 200; i++, now += 50) d.measure(10 + 300 * d.ratio ** 2, now, 24);
  assert.equal(d.ratio, RATIOS[RATIOS.length - 1]); // at most the last step, however slow
  for (let i = 0, now = 10000; i < 200; i++, now += 50) d.measure(5, now, 24);
  assert.equal(d.ratio, 1);
});

test('dynamic resolution: a paused page is drawn at full resolution', () => {
  const { d } = settle((r) => 10 + 100 * r * r, 100);
  assert.ok(d.ratio < 1);
  assert.equal(d.full(), true); // changed: the caller redraws
  assert.equal(d.ratio, 1);
  assert.equal(d.full(), false);
});

test('frontFaces: the faces of a tet that face the eye, and no others', () => {
  const tet = Float32Array.of(0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1), index = new Uint32Array(12);
  assert.equal(frontFaces(tet, 1, { x: 0.2, y: 0.2, z: 10 }, index), 3); // above: the slanted face alone
  assert.deepEqual([...index.slice(0, 3)].sort(), [1, 2, 3]);
  assert.equal(frontFaces(tet, 1, { x: -5, y: -4, z: -3 }, index), 9); // below the corner: its three faces
  assert.deepEqual(new Set(index.slice(0, 9)).size, 4);
});

test('frontFaces agrees with faces turned away from the opposite vertex, on random tets', () => {
  let seed = 7;
  const rand = () => ((seed = (seed * 1103515245 + 12345) % 2147483648) / 2147483648) * 20 - 10;
  const agents = 200, v = new Float32Array(12 * agents), index = new Uint32Array(12 * agents);
  for (let a = 0; a < agents; a++) {
    for (let i = 0; i < 12; i++) v[12 * a + i] = rand();
    const d = (i, k) => v[12 * a + 3 * i + k] - v[12 * a + k];
    const det = d(1, 0) * (d(2, 1) * d(3, 2) - d(2, 2) * d(3, 1)) - d(1, 1) * (d(2, 0) * d(3, 2) - d(2, 2) * d(3, 0))
      + d(1, 2) * (d(2, 0) * d(3, 1) - d(2, 1) * d(3, 0));
    if (det < 0) for (let k = 0; k < 3; k++) [v[12 * a + 3 + k], v[12 * a + 6 + k]] = [v[12 * a + 6 + k], v[12 * a + 3 + k]];
  }
  const eye = { x: 31, y: -17, z: 23 }, count = frontFaces(v, agents, eye, index);
  let expected = 0;
  for (let a = 0; a < agents; a++) for (let skip = 0; skip < 4; skip++) { // the face without vertex `skip`
    const p = [0, 1, 2, 3].filter((i) => i !== skip).map((i) => [0, 1, 2].map((k) => v[12 * a + 3 * i + k]));
    const far = [0, 1, 2].map((k) => v[12 * a + 3 * skip + k]);
    const u = [0, 1, 2].map((k) => p[1][k] - p[0][k]), w = [0, 1, 2].map((k) => p[2][k] - p[0][k]);
    let n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
    if (n.reduce((s, x, k) => s + x * (far[k] - p[0][k]), 0) > 0) n = n.map((x) => -x); // away from the far vertex
    if (n.reduce((s, x, k) => s + x * ([eye.x, eye.y, eye.z][k] - p[0][k]), 0) > 0) expected++;
  }
  assert.equal(count, 3 * expected);
  for (let i = 0; i < count; i += 3) assert.equal(Math.floor(index[i] / 4), Math.floor(index[i + 2] / 4)); // one tet's
});

test('frontFaces draws a tet smaller than `tiny` pixels as its one face that faces the eye most', () => {
  const tet = Float32Array.of(0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1), index = new Uint32Array(12);
  const eye = { x: -50, y: -40, z: -30 }; // 70.7 units away; three faces face it, the x = 0 face most
  // 100 px a unit at distance 1: its largest face (|n| = sqrt 3) is 3^(1/4) 100 / 70.7 = 1.9 px across
  assert.equal(frontFaces(tet, 1, eye, index, 100, 1), 9); // over 1 px: every front face
  assert.equal(frontFaces(tet, 1, eye, index, 100, 3), 3); // under 3 px: one face,
  assert.deepEqual([...index.slice(0, 3)].sort(), [0, 2, 3]); // the x = 0 one
});

test('dynamic resolution: where a smaller canvas does not pay, it goes back to full resolution and stays', () => {
  const { seen } = settle(() => 50, 400); // 50 ms whatever the pixels: over budget at every ratio
  assert.ok(seen.includes(0.75), 'it tries a step down');
  assert.equal(seen[seen.length - 1], 1);
  const changes = seen.filter((r, i) => i > 0 && r !== seen[i - 1]).length;
  assert.ok(changes <= 6, `no see-saw: ${changes} changes in 20 s`);
});

test('dynamic resolution: a page that shows the frame rate keeps its resolution, however long frames seem', () => {
  const d = new DynamicResolution();
  for (let i = 0, now = 0; i < 200; i++, now += 50) d.measure(60, now, 24, 24); // slow ticks, every frame shown
  assert.equal(d.ratio, 1);
});

// A unit cube as six positively oriented tets (Kuhn's: each along one path from corner 0 to 7).
function cubeTets() {
  const corner = (c) => [c & 1, (c >> 1) & 1, (c >> 2) & 1];
  const paths = [[1, 2, 4], [1, 4, 2], [2, 1, 4], [2, 4, 1], [4, 1, 2], [4, 2, 1]];
  const v = new Float32Array(12 * paths.length);
  paths.forEach((p, a) => {
    const c = [0, p[0], p[0] + p[1], 7].map(corner);
    const d = (i, k) => c[i][k] - c[0][k];
    const det = d(1, 0) * (d(2, 1) * d(3, 2) - d(2, 2) * d(3, 1)) - d(1, 1) * (d(2, 0) * d(3, 2) - d(2, 2) * d(3, 0))
      + d(1, 2) * (d(2, 0) * d(3, 1) - d(2, 1) * d(3, 0));
    if (det < 0) [c[1], c[2]] = [c[2], c[1]];
    c.flat().forEach((x, i) => { v[12 * a + i] = x; });
  });
  return v;
}

// The drawn faces as sorted corner coordinates (one string a face).
function drawnFaces(v, index, count) {
  const out = [];
  for (let i = 0; i < count; i += 3) out.push([0, 1, 2].map((j) => Array.from(v.slice(3 * index[i + j], 3 * index[i + j] + 3)).join(',')).sort().join(' '));
  return out.sort();
}

test('sharedFaces finds the tet across each inner face of a shape, none on its surface', () => {
  const v = cubeTets(), across = sharedFaces(v, 6);
  const seen = new Map(); // each face's corners, counted over every tet: 2 inside the cube, 1 on its surface
  for (let a = 0; a < 6; a++) for (let f = 0; f < 4; f++) {
    const k = drawnFaces(v, TET_FACES.slice(3 * f, 3 * f + 3).map((c) => 4 * a + c), 3)[0];
    seen.set(k, [...(seen.get(k) ?? []), [a, f]]);
  }
  for (const owners of seen.values()) {
    if (owners.length === 1) assert.equal(across[4 * owners[0][0] + owners[0][1]], -1);
    else assert.deepEqual(owners.map(([a, f]) => across[4 * a + f]), [owners[1][0], owners[0][0]]);
  }
  assert.equal([...seen.values()].filter((o) => o.length === 1).length, 12, 'a cube: 6 faces of 2 triangles');
});

test('frontFaces draws a shape at rest as its surface, and a tet that moved whole', () => {
  const v = cubeTets(), eye = { x: 5, y: -7, z: 9 }, index = new Uint32Array(72);
  const shape = { v: v.slice(), across: sharedFaces(v, 6) }, resting = new Uint8Array(6);
  const all = drawnFaces(v, index, frontFaces(v, 6, eye, index));
  const surface = drawnFaces(v, index, frontFaces(v, 6, eye, index, 0, 0, restingTets(v, 6, [shape, null], resting)));
  assert.deepEqual([...resting], [1, 1, 1, 1, 1, 1]);
  assert.equal(surface.length, 6, 'three faces of the cube face the eye: two triangles each');
  const inner = new Set(all.filter((k, i) => all.indexOf(k) !== i || all.lastIndexOf(k) !== i));
  assert.ok(surface.every((k) => all.includes(k) && !inner.has(k)), 'only faces drawn before, none between two tets');
  for (let i = 0; i < 12; i++) v[i] += 0.25; // tet 0 has moved: it is drawn whole, and so are the faces it left
  const moved = drawnFaces(v, index, frontFaces(v, 6, eye, index, 0, 0, restingTets(v, 6, [shape, null], resting)));
  assert.deepEqual([...resting], [0, 1, 1, 1, 1, 1]);
  const between = new Map(); // the faces of the tets that stay, counted: 2 where two of them share one
  for (let a = 1; a < 6; a++) for (let f = 0; f < 4; f++) {
    const k = drawnFaces(v, TET_FACES.slice(3 * f, 3 * f + 3).map((c) => 4 * a + c), 3)[0];
    between.set(k, (between.get(k) ?? 0) + 1);
  }
  const expected = drawnFaces(v, index, frontFaces(v, 6, eye, index)).filter((k) => between.get(k) !== 2);
  assert.deepEqual(moved, expected);
  assert.ok(moved.length > surface.length, 'the faces tet 0 left are drawn again');
});
