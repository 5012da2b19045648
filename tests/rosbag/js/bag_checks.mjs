// Checks of decoded ROS 2 messages for inspect_bag.mjs --check, and the
// short JSON form of a message for its samples.

// Eigenvalues of a symmetric n x n matrix (row-major array), cyclic Jacobi.
export function symmetricEigenvalues(a, n) {
  const m = Array.from({ length: n }, (_, i) => Array.from({ length: n }, (_, j) => a[i * n + j]));
  for (let sweep = 0; sweep < 100; ++sweep) {
    let off = 0;
    for (let i = 0; i < n; ++i) for (let j = i + 1; j < n; ++j) off += m[i][j] ** 2;
    if (off < 1e-30) break;
    for (let p = 0; p < n; ++p) {
      for (let q = p + 1; q < n; ++q) {
        if (m[p][q] === 0) continue;
        const theta = (m[q][q] - m[p][p]) / (2 * m[p][q]);
        const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
        const c = 1 / Math.sqrt(t * t + 1), s = t * c;
        for (let k = 0; k < n; ++k) {  // columns p, q
          const kp = m[k][p], kq = m[k][q];
          m[k][p] = c * kp - s * kq;
          m[k][q] = s * kp + c * kq;
        }
        for (let k = 0; k < n; ++k) {  // rows p, q
          const pk = m[p][k], qk = m[q][k];
          m[p][k] = c * pk - s * qk;
          m[q][k] = s * pk + c * qk;
        }
      }
    }
  }
  return m.map((r, i) => r[i]);
}

// Why `cov` (length 9 or 36, row-major) is not a symmetric positive
// semi-definite matrix, or null. cov[0] == -1 is ROS's "no estimate".
export function covarianceProblem(cov) {
  if (cov[0] === -1) return null;
  const n = cov.length === 9 ? 3 : 6;
  if (cov.some((x) => !Number.isFinite(x))) return "has a non-finite element";
  const scale = Math.max(1e-300, ...cov.map(Math.abs));
  for (let i = 0; i < n; ++i) {
    for (let j = i + 1; j < n; ++j) {
      if (Math.abs(cov[i * n + j] - cov[j * n + i]) > 1e-9 * scale)
        return `not symmetric ([${i}][${j}] = ${cov[i * n + j]}, [${j}][${i}] = ${cov[j * n + i]})`;
    }
  }
  const minEig = Math.min(...symmetricEigenvalues(cov, n));
  if (minEig < -1e-9 * scale) return `not positive semi-definite (eigenvalue ${minEig})`;
  return null;
}

// Calls visit(path, array) for every field whose name contains "covariance"
// and holds 9 or 36 numbers, anywhere in a decoded message.
export function forEachCovariance(msg, visit, path = "") {
  if (msg === null || typeof msg !== "object" || ArrayBuffer.isView(msg)) return;
  if (Array.isArray(msg)) {
    msg.forEach((v, i) => forEachCovariance(v, visit, `${path}[${i}]`));
    return;
  }
  for (const [key, value] of Object.entries(msg)) {
    const p = path ? `${path}.${key}` : key;
    const isNumbers = (Array.isArray(value) || (ArrayBuffer.isView(value) && !(value instanceof DataView))) &&
                      (value.length === 9 || value.length === 36) && [...value].every((x) => typeof x === "number");
    if (key.includes("covariance") && isNumbers) visit(p, [...value]);
    else forEachCovariance(value, visit, p);
  }
}

// header.stamp (or stamp) as BigInt ns, or null.
export function stampNs(msg) {
  const s = msg?.header?.stamp ?? null;
  if (!s || typeof s.sec !== "number") return null;
  return BigInt(s.sec) * 1000000000n + BigInt(s.nanosec ?? s.nsec ?? 0);
}

// A decoded message as JSON: long arrays become "<Type[length]>", BigInts
// strings, NaN "NaN".
export function shortForm(v) {
  if (typeof v === "bigint") return v.toString();
  if (typeof v === "number" && !Number.isFinite(v)) return String(v);
  if (ArrayBuffer.isView(v) || Array.isArray(v)) {
    if (v.length > 12) return `<${v.constructor.name}[${v.length}]>`;
    return [...v].map(shortForm);
  }
  if (v && typeof v === "object") return Object.fromEntries(Object.entries(v).map(([k, x]) => [k, shortForm(x)]));
  return v;
}
