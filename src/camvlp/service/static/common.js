// What the site's pages share: the site's key (from the link's #key=... or the user, kept in
// this tab's sessionStorage only), API requests that carry it, and the plan from above with
// its grid and fixtures. An ES module, loaded by site.js and capture.js; no build step.

export const SVG_NS = "http://www.w3.org/2000/svg";
export const VIEW_W = 800, VIEW_H = 600, PAD = 48;

export const $ = (id) => document.getElementById(id);

// The site's id from the address (/sites/ID or /sites/ID/capture), or NaN.
export const siteId = Number((location.pathname.match(/\/sites\/(\d+)/) || [])[1]);
const keyName = `camvlp.key.${siteId}`;

// The key from the address's fragment (then removed from the address bar), else the tab's.
export function takeKeyFromFragment() {
  const m = location.hash.match(/(?:^#|&)key=([^&]+)/);
  if (m) {
    sessionStorage.setItem(keyName, decodeURIComponent(m[1]));
    history.replaceState(null, "", location.pathname + location.search);
  }
  return sessionStorage.getItem(keyName);
}

export function saveKey(key) { sessionStorage.setItem(keyName, key); }
export function forgetKey() { sessionStorage.removeItem(keyName); }

// fetch() of /api/v1/sites/ID/PATH with the key; an answer that is not 2xx throws an Error
// with the service's one-line detail and the HTTP status.
export async function api(key, path, options = {}) {
  const headers = Object.assign({}, options.headers, { Authorization: `Bearer ${key}` });
  const response = await fetch(`/api/v1/sites/${siteId}${path}`, { ...options, headers });
  if (!response.ok) {
    let detail = `${response.status} ${response.statusText}`;
    try { detail = (await response.json()).detail || detail; } catch (e) { /* not JSON */ }
    const error = new Error(detail);
    error.status = response.status;
    throw error;
  }
  return response;
}

export function svg(tag, attrs = {}, parent = null, text = null) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  if (text !== null) el.textContent = text;
  if (parent) parent.appendChild(el);
  return el;
}

function niceStep(span) {
  const raw = span / 8, p = Math.pow(10, Math.floor(Math.log10(raw)));
  return [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw);
}

// Plan coordinates (map units, first axis right, second axis up) -> SVG pixels.
function projection(points) {
  let [minA, maxA, minB, maxB] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const [a, b] of points) {
    minA = Math.min(minA, a); maxA = Math.max(maxA, a);
    minB = Math.min(minB, b); maxB = Math.max(maxB, b);
  }
  const span = Math.max(maxA - minA, maxB - minB, 1e-6);
  minA -= 0.15 * span; maxA += 0.15 * span; minB -= 0.15 * span; maxB += 0.15 * span;
  const s = Math.min((VIEW_W - 2 * PAD) / (maxA - minA), (VIEW_H - 2 * PAD) / (maxB - minB));
  const offA = PAD + ((VIEW_W - 2 * PAD) - s * (maxA - minA)) / 2;
  const offB = PAD + ((VIEW_H - 2 * PAD) - s * (maxB - minB)) / 2;
  return {
    s, minA, maxA, minB, maxB,
    x: (a) => offA + (a - minA) * s,
    y: (b) => VIEW_H - offB - (b - minB) * s,
  };
}

// Draw the site's plan into the <svg> `plan`: grid, axis names, the fixtures (class
// "fixture", data-fixture-id; class "used" for the IDs in `used`). `points` are more plan
// points to keep in view. Returns the projection (P.x, P.y, P.s: pixels per map unit).
export function drawBasePlan(plan, site, points = [], used = new Set()) {
  plan.replaceChildren();
  const P = projection(site.fixtures.map((f) => f.plan).concat(points));
  const grid = svg("g", { class: "grid" }, plan);
  const step = niceStep(Math.max(P.maxA - P.minA, P.maxB - P.minB));
  for (let a = Math.ceil(P.minA / step) * step; a <= P.maxA; a += step) {
    svg("line", { x1: P.x(a), x2: P.x(a), y1: 0, y2: VIEW_H }, grid);
    svg("text", { x: P.x(a) + 3, y: VIEW_H - 6 }, grid, `${+a.toFixed(6)}`);
  }
  for (let b = Math.ceil(P.minB / step) * step; b <= P.maxB; b += step) {
    svg("line", { x1: 0, x2: VIEW_W, y1: P.y(b), y2: P.y(b) }, grid);
    svg("text", { x: 4, y: P.y(b) - 3 }, grid, `${+b.toFixed(6)}`);
  }
  const [nameA, nameB] = site.plan.axis_names;
  svg("text", { class: "axis-label", x: VIEW_W - 70, y: 18 }, plan, `${nameA} → (${site.units})`);
  svg("text", { class: "axis-label", x: VIEW_W - 70, y: 34 }, plan, `${nameB} ↑ (${site.units})`);
  const fixtures = svg("g", { class: "fixtures" }, plan);
  for (const f of site.fixtures) {
    const cls = used.has(f.id) ? "fixture used" : "fixture";
    const g = svg("g", { class: cls, "data-fixture-id": f.id }, fixtures);
    const r = Math.max(6, ((f.diameter || 0) * P.s) / 2);
    svg("circle", { cx: P.x(f.plan[0]), cy: P.y(f.plan[1]), r }, g);
    svg("text", { x: P.x(f.plan[0]) + r + 4, y: P.y(f.plan[1]) + 4 }, g, `ID ${f.id}`);
  }
  return P;
}

// A dot with its heading line and a label, at plan position `pos` (class `cls`).
export function drawDot(layer, P, pos, headingDeg, label, attrs) {
  const g = svg("g", attrs, layer);
  const x = P.x(pos[0]), y = P.y(pos[1]);
  let away = [1, 0];  // the label goes on the side the heading does not point to
  if (headingDeg !== null && headingDeg !== undefined) {
    const t = (headingDeg * Math.PI) / 180;
    svg("line", { x1: x, y1: y, x2: x + 26 * Math.cos(t), y2: y - 26 * Math.sin(t) }, g);
    away = [-Math.cos(t), Math.sin(t)];
  }
  svg("circle", { cx: x, cy: y, r: 8 }, g);
  svg("text", {
    x: x + 14 * away[0], y: y + 14 * away[1] + 4,
    "text-anchor": away[0] < -0.3 ? "end" : away[0] > 0.3 ? "start" : "middle",
  }, g, label);
  return g;
}

export function fmtPosition(p) {
  return p ? `(${p.map((v) => v.toFixed(3)).join(", ")})` : "—";
}

export function fmtSigma(s) {  // two significant digits: a good fix's are well under a millimetre
  return `(${s.map((v) => v.toPrecision(2)).join(", ")})`;
}
