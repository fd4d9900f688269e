// Unit tests of the page's pure parts, under node's own test runner (no browser):
//   node --test web/test/          (ctest: test_studio_page)
// protocol.js's frame parsing against the layout docs/studio.md gives, path.js's arc-length
// resampling of a sketch, panel.js's dotted keys.
import assert from 'node:assert/strict';
import { test } from 'node:test';
import * as THREE from 'three';
import { ATTR, parseFrame } from '../src/protocol.js';
import { resample } from '../src/path.js';
import { getKey } from '../src/panel.js';

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
