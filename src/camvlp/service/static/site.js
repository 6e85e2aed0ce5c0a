// The live page of one site: its plan from above, the fixes as they arrive, an upload form.
// Every API request carries the site's key in the Authorization header; the key comes from
// the URL fragment (#key=..., never sent to the server) or from the user, and is kept in this
// tab's sessionStorage only (common.js).
import {
  $, api as siteApi, drawBasePlan, drawDot, fmtPosition, fmtSigma, forgetKey, saveKey, siteId,
  svg, takeKeyFromFragment,
} from "/static/common.js";

const TRAIL_LENGTH = 20;     // fixes per device drawn as its trail
const MAX_FIXES = 500;       // fixes kept in the page

const state = { site: null, fixes: new Map(), lastId: 0, key: null, stream: null };

const api = (path, options = {}) => siteApi(state.key, path, options);

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
  if (!state.site) { plan.replaceChildren(); return; }
  const byDevice = fixesByDevice();
  const points = [];
  for (const list of byDevice.values()) {
    for (const fix of list.slice(-TRAIL_LENGTH)) points.push(fix.plan.position);
  }
  const P = drawBasePlan(plan, state.site, points);
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
    drawDot(fixLayer, P, last.plan.position, last.plan.heading_deg,
      `${device || "(no name)"} #${last.id}`,
      { class: "fix latest", "data-fix-id": last.id, "data-device": device });
  }
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
    if (error.status === 401 || error.status === 403 || error.status === 404) forgetKey();
    showKeyPanel(error.message);
    return;
  }
  $("key-panel").hidden = true;
  $("main").hidden = false;
  $("site-name").textContent = state.site.name;
  $("site-id").textContent = `site ${siteId}`;
  $("capture-link").href = `/sites/${siteId}/capture`;
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
  saveKey(state.key);
  openSite();
});
$("locate-form").addEventListener("submit", locatePhoto);

state.key = takeKeyFromFragment();
if (!Number.isInteger(siteId) || siteId <= 0) showKeyPanel("no site in this address");
else if (state.key) openSite();
else showKeyPanel("");
