// Area-weighted vertex normals, for meshes and frames that come without them.

export function computeNormals(positions: Float32Array, index: Uint32Array, normals: Float32Array): void {
  normals.fill(0);
  const p = positions;
  for (let t = 0; t < index.length; t += 3) {
    const i = index[t] * 3, j = index[t + 1] * 3, k = index[t + 2] * 3;
    const ax = p[j] - p[i], ay = p[j + 1] - p[i + 1], az = p[j + 2] - p[i + 2];
    const bx = p[k] - p[i], by = p[k + 1] - p[i + 1], bz = p[k + 2] - p[i + 2];
    const cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
    for (const v of [i, j, k]) {
      normals[v] += cx;
      normals[v + 1] += cy;
      normals[v + 2] += cz;
    }
  }
  for (let v = 0; v < normals.length; v += 3) {
    const l = Math.hypot(normals[v], normals[v + 1], normals[v + 2]) || 1;
    normals[v] /= l;
    normals[v + 1] /= l;
    normals[v + 2] /= l;
  }
}
