// The live page of one site: its plan from above, the fixes as they arrive, an upload form.
// Every API request carries the site's key in the Authorization header; the key comes from
// the URL fragment (#key=..., never sent to the server) or from the user, and is kept in this
// tab's sessionStorage only.
"use strict";

const SVG_NS = "http://www.w3.org/2000/svg";
const VIEW_W = 800, VIEW_H = 600, PAD = 48;
const TRAIL_LENGTH = 20;     // fixes per device drawn as its trail
const MAX_FIXES = 500;       // fixes kept in the page

const siteId = Number((location.pathname.match(/\/sites\/(\d+)/) || [])[1]);
const keyName = `camvlp.key.${siteId}`;
const state = { site: null, fixes: new Map(), lastId: 0, key: null, stream: null };

const $ = (id) => document.getElementById(id);

function takeKeyFromFragment() {
  const m = location.hash.match(/(?:^#|&)key=([^&]+)/);
  if (m) {
    sessionStorage.setItem(keyName, decodeURIComponent(m[1]));
    history.replaceState(null, "", location.pathname + location.search);
  }
  return sessionStorage.getItem(keyName);
}

async function api(path, options = {}) {
  const headers = Object.assign({}, options.headers, { Authorization: `Bearer ${state.key}` });
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

function svg(tag, attrs = {}, parent = null, text = null) {
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

function fixesByDevice() {
  const byDevice = new Map();
  for (const fix of [...state.fixes.values()].sort((p, q) => p.id - q.id)) {
    if (!fix.located || !fix.plan.position) continue;
    if (!byDevice.has(fix.device)) byDevice.set(fix.device, []);
    byDevice.get(fix.device).push(fix);
  }
  return byDevice;
}

function drawPlan() {
  const plan = $("plan");
  plan.replaceChildren();
  if (!state.site) return;
  const units = state.site.units;
  const byDevice = fixesByDevice();
  const points = state.site.fixtures.map((f) => f.plan);
  for (const list of byDevice.values()) {
    for (const fix of list.slice(-TRAIL_LENGTH)) points.push(fix.plan.position);
  }
  const P = projection(points);

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
  const [nameA, nameB] = state.site.plan.axis_names;
  svg("text", { class: "axis-label", x: VIEW_W - 70, y: 18 }, plan, `${nameA} → (${units})`);
  svg("text", { class: "axis-label", x: VIEW_W - 70, y: 34 }, plan, `${nameB} ↑ (${units})`);

  const fixtures = svg("g", { class: "fixtures" }, plan);
  for (const f of state.site.fixtures) {
    const g = svg("g", { class: "fixture", "data-fixture-id": f.id }, fixtures);
    const r = Math.max(6, ((f.diameter || 0) * P.s) / 2);
    svg("circle", { cx: P.x(f.plan[0]), cy: P.y(f.plan[1]), r }, g);
    svg("text", { x: P.x(f.plan[0]) + r + 4, y: P.y(f.plan[1]) + 4 }, g, `ID ${f.id}`);
  }

  const fixLayer = svg("g", { class: "fixes" }, plan);
  for (const [device, list] of byDevice) {
    const recent = list.slice(-TRAIL_LENGTH);
    const pts = recent.map((fx) => `${P.x(fx.plan.position[0])},${P.y(fx.plan.position[1])}`);
    svg("polyline", { class: "trail", points: pts.join(" "), "data-device": device }, fixLayer);
    for (const fx of recent.slice(0, -1)) {
      svg("circle", { class: "trail-point", cx: P.x(fx.plan.position[0]),
        cy: P.y(fx.plan.position[1]), r: 3 }, fixLayer);
    }
    const last = recent[recent.length - 1];
    const g = svg("g", { class: "fix latest", "data-fix-id": last.id, "data-device": device },
      fixLayer);
    const x = P.x(last.plan.position[0]), y = P.y(last.plan.position[1]);
    let away = [1, 0];  // the label goes on the side the heading does not point to
    if (last.plan.heading_deg !== null) {
      const t = (last.plan.heading_deg * Math.PI) / 180;
      svg("line", { x1: x, y1: y, x2: x + 26 * Math.cos(t), y2: y - 26 * Math.sin(t) }, g);
      away = [-Math.cos(t), Math.sin(t)];
    }
    svg("circle", { cx: x, cy: y, r: 8 }, g);
    svg("text", {
      x: x + 14 * away[0], y: y + 14 * away[1] + 4,
      "text-anchor": away[0] < -0.3 ? "end" : away[0] > 0.3 ? "start" : "middle",
    }, g, `${device || "(no name)"} #${last.id}`);
  }
}

function fmtPosition(p) {
  return p ? `(${p.map((v) => v.toFixed(3)).join(", ")})` : "—";
}

function fmtSigma(s) {  // two significant digits: a good fix's are well under a millimetre
  return `(${s.map((v) => v.toPrecision(2)).join(", ")})`;
}

function drawTable() {
  const body = $("fixes").querySelector("tbody");
  body.replaceChildren();
  const recent = [...state.fixes.values()].sort((p, q) => q.id - p.id).slice(0, 30);
  for (const fix of recent) {
    const tr = document.createElement("tr");
    const cells = [
      `${fix.id}`, fix.time.slice(11, 19), fix.device || "—",
      fix.located ? fmtPosition(fix.position) : fix.error,
      fix.reprojection_rms_px === null ? "—" : fix.reprojection_rms_px.toFixed(2),
    ];
    cells.forEach((text, i) => {
      const td = document.createElement("td");
      td.textContent = text;
      if (i === 3 && !fix.located) td.className = "failed";
      tr.appendChild(td);
    });
    body.appendChild(tr);
  }
}

function addFix(fix) {
  state.fixes.set(fix.id, fix);
  state.lastId = Math.max(state.lastId, fix.id);
  if (state.fixes.size > MAX_FIXES) {
    const oldest = Math.min(...state.fixes.keys());
    state.fixes.delete(oldest);
  }
  drawPlan();
  drawTable();
}

function setStatus(live, text) {
  const el = $("status");
  el.className = `status ${live ? "live" : "off"}`;
  el.textContent = text;
}

// Server-sent events over fetch (EventSource cannot send an Authorization header).
async function followStream() {
  for (;;) {
    try {
      const response = await api(`/fixes/stream?after=${state.lastId}`, {
        headers: { Accept: "text/event-stream" },
      });
      setStatus(true, "live");
      const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
      let buffer = "";
      for (;;) {
        const { value, done } = await reader.read();
        if (done) break;
        buffer += value;
        let cut;
        while ((cut = buffer.indexOf("\n\n")) >= 0) {
          const block = buffer.slice(0, cut);
          buffer = buffer.slice(cut + 2);
          const data = block.split("\n").filter((l) => l.startsWith("data:"))
            .map((l) => l.slice(5).trimStart()).join("\n");
          if (block.includes("event: fix") && data) addFix(JSON.parse(data));
        }
      }
    } catch (error) {
      if (error.status === 401 || error.status === 403) { showKeyPanel(error.message); return; }
    }
    setStatus(false, "reconnecting");
    await new Promise((resolve) => setTimeout(resolve, 2000));
  }
}

function showResult(result) {
  $("result").hidden = false;
  $("result-id").textContent = `#${result.fix_id}`;
  const used = result.fixtures.filter((f) => f.used).map((f) => f.id);
  const lines = result.position
    ? [`position ${fmtPosition(result.position)} ${state.site.units}`,
       ...(result.position_sigma
         ? [`uncertainty ${fmtSigma(result.position_sigma)} ${state.site.units} (1σ)`]
         : []),
       `orientation θ = (${result.euler_deg.map((v) => v.toFixed(1)).join(", ")})°`,
       `reprojection ${result.reprojection_rms_px} px RMS`,
       `fixtures used: ${used.join(", ")} of ${result.fixtures.length} found`]
    : [`not located: ${result.error}`, `${result.fixtures.length} fixtures found`];
  $("result-text").textContent = lines.join("\n");
}

async function locatePhoto(event) {
  event.preventDefault();
  const button = $("locate-button");
  $("error").hidden = true;
  button.disabled = true;
  try {
    const form = new FormData();
    form.append("photo", $("photo").files[0]);
    form.append("device", $("device").value);
    form.append("annotate", "true");
    const camera = encodeURIComponent($("camera").value);
    const result = await (await api(`/locate?camera=${camera}`, { method: "POST", body: form }))
      .json();
    showResult(result);
    const fix = await (await api(`/fixes/${result.fix_id}`)).json();
    addFix(fix);
    const img = $("annotated");
    if (fix.has_picture) {
      const blob = await (await api(`/fixes/${result.fix_id}/picture`)).blob();
      if (img.src) URL.revokeObjectURL(img.src);
      img.src = URL.createObjectURL(blob);
      img.hidden = false;
    } else {
      img.hidden = true;
    }
  } catch (error) {
    $("error").textContent = error.message;
    $("error").hidden = false;
  } finally {
    button.disabled = false;
  }
}

function showKeyPanel(message) {
  $("main").hidden = true;
  $("key-panel").hidden = false;
  $("key-error").hidden = !message;
  $("key-error").textContent = message || "";
  setStatus(false, "offline");
}

async function openSite() {
  try {
    state.site = await (await api("")).json();
  } catch (error) {
    if (error.status === 401 || error.status === 403 || error.status === 404) {
      sessionStorage.removeItem(keyName);
    }
    showKeyPanel(error.message);
    return;
  }
  $("key-panel").hidden = true;
  $("main").hidden = false;
  $("site-name").textContent = state.site.name;
  $("site-id").textContent = `site ${siteId}`;
  document.title = `camvlp · ${state.site.name}`;
  $("camera").replaceChildren(...Object.keys(state.site.cameras).map((name) => {
    const option = document.createElement("option");
    option.value = option.textContent = name;
    return option;
  }));
  const page = await (await api("/fixes?limit=200")).json();
  for (const fix of page.fixes.reverse()) state.fixes.set(fix.id, fix);
  state.lastId = Math.max(0, ...state.fixes.keys());
  drawPlan();
  drawTable();
  followStream();
}

$("key-form").addEventListener("submit", (event) => {
  event.preventDefault();
  state.key = $("key-input").value.trim();
  sessionStorage.setItem(keyName, state.key);
  openSite();
});
$("locate-form").addEventListener("submit", locatePhoto);

state.key = takeKeyFromFragment();
if (!Number.isInteger(siteId) || siteId <= 0) showKeyPanel("no site in this address");
else if (state.key) openSite();
else showKeyPanel("");
