// Tets as triangles: each tet's four faces from its vertices 0..3 (the cache's order, a positively
// oriented tet), wound so that they face out. Only the faces that face the eye are drawn: they are
// found here on the CPU, once a frame, and written to the index buffer in place, because a software
// rasterizer (SwiftShader) spends its time per triangle set up, not per pixel, and a GPU's own
// culling of back faces comes after that set-up. A tet smaller on the screen than `tiny` pixels
// (its largest face's size) is drawn as the one face that faces the eye most, which covers most of
// its outline: at that size the eye cannot tell. A tet turned inside out has its far faces drawn:
// it still looks like a tet.
export const TET_FACES = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];

// Writes to index the faces of the agents' tets (12 floats each in v) that face eye (x, y, z), as
// vertex indices 4 a + corner, and returns how many indices it wrote (a multiple of 3).
// pixelsPerUnit: a unit's size on the screen at distance 1 (the camera's); tiny: in pixels (0:
// every front face of every tet).
export function frontFaces(v, agents, eye, index, pixelsPerUnit = 0, tiny = 0) {
  let count = 0;
  const ex = eye.x, ey = eye.y, ez = eye.z, k4 = tiny > 0 ? (pixelsPerUnit / tiny) ** 4 : Infinity;
  const facing = [0, 0, 0, 0];
  for (let a = 0; a < agents; a++) {
    const o = 12 * a;
    let best = 0, largest = 0;
    for (let f = 0; f < 4; f++) {
      const p = o + 3 * TET_FACES[3 * f], q = o + 3 * TET_FACES[3 * f + 1], r = o + 3 * TET_FACES[3 * f + 2];
      const ax = v[p], ay = v[p + 1], az = v[p + 2];
      const ux = v[q] - ax, uy = v[q + 1] - ay, uz = v[q + 2] - az;
      const wx = v[r] - ax, wy = v[r + 1] - ay, wz = v[r + 2] - az;
      const nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
      facing[f] = nx * (ex - ax) + ny * (ey - ay) + nz * (ez - az); // twice its area seen from the eye, times distance
      if (facing[f] > facing[best]) best = f;
      largest = Math.max(largest, nx * nx + ny * ny + nz * nz);
    }
    // |n| (twice the largest face's area) seen at distance d: (|n| k^2 / d^2) square pixels
    const dx = ex - v[o], dy = ey - v[o + 1], dz = ez - v[o + 2], d2 = dx * dx + dy * dy + dz * dz;
    const small = largest * k4 < d2 * d2;
    for (let f = 0; f < 4; f++) {
      if (!(facing[f] > 0) || (small && f !== best)) continue;
      index[count] = 4 * a + TET_FACES[3 * f]; index[count + 1] = 4 * a + TET_FACES[3 * f + 1];
      index[count + 2] = 4 * a + TET_FACES[3 * f + 2];
      count += 3;
    }
  }
  return count;
}
