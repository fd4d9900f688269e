// Tets as triangles: each tet's four faces from its vertices 0..3 (the cache's order, a positively
// oriented tet), wound so that they face out. Only the faces that face the eye are drawn: they are
// found here on the CPU, once a frame (three cross products a tet: the fourth face's normal is minus
// the sum of the other three), and written to the index buffer in place, because a software
// rasterizer (SwiftShader) spends its time per triangle set up, not per pixel, and a GPU's own
// culling of back faces comes after that set-up. A tet smaller on the screen than `tiny` pixels
// (its largest face's size) is drawn as the one face that faces the eye most, which covers most of
// its outline: at that size the eye cannot tell. A tet turned inside out has its far faces drawn:
// it still looks like a tet.
export const TET_FACES = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

// Writes to index the faces of the agents' tets (12 floats each in v) that face eye (x, y, z), as
// vertex indices 4 a + corner, and returns how many indices it wrote (a multiple of 3).
// pixelsPerUnit: a unit's size on the screen at distance 1 (the camera's); tiny: in pixels (0:
// every front face of every tet). rest (restingTets): the tets at rest in a shape, whose faces shared
// with another tet at rest in the same shape are left out, and which are drawn whole (no tiny rule):
// a face between two tets is hidden by the tet on the eye's side of it, so the shape is drawn as
// its surface, and the picture is the same.
export function frontFaces(v, agents, eye, index, pixelsPerUnit = 0, tiny = 0, rest = null) {
  let count = 0;
  const ex = eye.x, ey = eye.y, ez = eye.z, k4 = tiny > 0 ? (pixelsPerUnit / tiny) ** 4 : Infinity;
  const facing = new Float64Array(4);
  for (let a = 0; a < agents; a++) {
    const o = 12 * a;
    let best = 0, largest = 0, sx = 0, sy = 0, sz = 0;
    for (let f = 0; f < 4; f++) {
      const p = o + 3 * TET_FACES[3 * f];
      const ax = v[p], ay = v[p + 1], az = v[p + 2];
      let nx, ny, nz;
      if (f < 3) {
        const q = o + 3 * TET_FACES[3 * f + 1], r = o + 3 * TET_FACES[3 * f + 2];
        const ux = v[q] - ax, uy = v[q + 1] - ay, uz = v[q + 2] - az;
        const wx = v[r] - ax, wy = v[r + 1] - ay, wz = v[r + 2] - az;
        nx = uy * wz - uz * wy; ny = uz * wx - ux * wz; nz = ux * wy - uy * wx;
        sx += nx; sy += ny; sz += nz;
      } else { nx = -sx; ny = -sy; nz = -sz; } // a closed tet's outward area normals sum to zero
      facing[f] = nx * (ex - ax) + ny * (ey - ay) + nz * (ez - az); // twice its area seen from the eye, times distance
      if (facing[f] > facing[best]) best = f;
      largest = Math.max(largest, nx * nx + ny * ny + nz * nz);
    }
    // |n| (twice the largest face's area) seen at distance d: (|n| k^2 / d^2) square pixels
    const dx = ex - v[o], dy = ey - v[o + 1], dz = ez - v[o + 2], d2 = dx * dx + dy * dy + dz * dz;
    const shape = rest ? rest.shape[a] : 0, across = shape ? rest.across[shape - 1] : null;
    const small = !shape && largest * k4 < d2 * d2;
    for (let f = 0; f < 4; f++) {
      if (!(facing[f] > 0) || (small && f !== best)) continue;
      if (across && across[4 * a + f] >= 0 && rest.shape[across[4 * a + f]] === shape) continue; // inside the shape
      index[count] = 4 * a + TET_FACES[3 * f]; index[count + 1] = 4 * a + TET_FACES[3 * f + 1];
      index[count + 2] = 4 * a + TET_FACES[3 * f + 2];
      count += 3;
    }
  }
  return count;
}

// Which tet lies across each face of each tet of a shape (12 floats a tet in v, as the frame has
// them): an Int32Array of 4 per tet, -1 where the face is on the shape's surface. Two faces are
// the same where their corners are the same to 2^-16 of the shape's size: the engine writes a
// corner as a tet's centre plus its offset, so the tets that share it round it a little apart (a
// corner that falls either side of a step leaves its faces drawn: the picture stays right).
// Typed-array hash tables: once per run and shape, a few tens of ms for words' 13,818 tets.
export function sharedFaces(v, agents) {
  const ids = vertexIds(v, 4 * agents), faces = 4 * agents, size = tableSize(faces);
  const table = new Int32Array(size).fill(-1), key = new Int32Array(3 * faces), across = new Int32Array(faces).fill(-1);
  for (let face = 0; face < faces; face++) {
    const a = face >> 2, f = face & 3, o = 3 * face;
    const i = ids[4 * a + TET_FACES[3 * f]], j = ids[4 * a + TET_FACES[3 * f + 1]], k = ids[4 * a + TET_FACES[3 * f + 2]];
    key[o] = Math.min(i, j, k); key[o + 2] = Math.max(i, j, k); key[o + 1] = i + j + k - key[o] - key[o + 2];
    for (let h = mix(key[o], key[o + 1], key[o + 2]) & (size - 1); ; h = (h + 1) & (size - 1)) {
      const other = table[h];
      if (other < 0) { table[h] = face; break; }
      if (key[3 * other] === key[o] && key[3 * other + 1] === key[o + 1] && key[3 * other + 2] === key[o + 2]) {
        across[face] = other >> 2; across[other] = a;
        break;
      }
    }
  }
  return across;
}

// Each of count corners (3 floats each) numbered so that corners in the same step of 2^-16 of the
// largest coordinate share a number.
function vertexIds(v, count) {
  let most = 1e-30;
  for (let i = 0; i < 3 * count; i++) most = Math.max(most, Math.abs(v[i]));
  const step = most / 65536, cell = new Int32Array(3 * count), size = tableSize(count);
  for (let i = 0; i < 3 * count; i++) cell[i] = Math.round(v[i] / step);
  const table = new Int32Array(size).fill(-1), ids = new Int32Array(count);
  let next = 0;
  for (let c = 0; c < count; c++) {
    const x = cell[3 * c], y = cell[3 * c + 1], z = cell[3 * c + 2];
    for (let h = mix(x, y, z) & (size - 1); ; h = (h + 1) & (size - 1)) {
      const other = table[h];
      if (other < 0) { table[h] = c; ids[c] = next++; break; }
      if (cell[3 * other] === x && cell[3 * other + 1] === y && cell[3 * other + 2] === z) { ids[c] = ids[other]; break; }
    }
  }
  return ids;
}

function tableSize(n) { let size = 16; while (size < 2 * n) size *= 2; return size; }
function mix(x, y, z) { return (Math.imul(x, 0x9e3779b1) ^ Math.imul(y, 0x85ebca77) ^ Math.imul(z, 0xc2b2ae3d)) >>> 0; }

// Which shape each tet is at rest in, for frontFaces: shape[a] = s + 1 where tet a's 12 floats are
// its own in shapes[s].v (a frame where the tets form the shape: the first, every tet waiting on the
// source, and the last, every tet arrived on the target), else 0. shape: a Uint8Array of agents.
export function restingTets(v, agents, shapes, shape) {
  shape.fill(0);
  shapes.forEach((s, i) => {
    if (!s) return;
    const r = s.v;
    for (let a = 0; a < agents; a++) {
      if (shape[a]) continue;
      let same = true;
      for (let o = 12 * a, end = o + 12; o < end && same; o++) same = v[o] === r[o];
      if (same) shape[a] = i + 1;
    }
  });
  return { shape, across: shapes.map((s) => s?.across ?? null) };
}
