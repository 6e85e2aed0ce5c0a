// The phone's page: the rear camera's frames (or full-resolution photos) sent one after
// another to POST /api/v1/sites/ID/frames with the phone's gravity, and the position shown on
// the site's plan as each answer arrives. One frame is in flight at a time: the next one is
// grabbed when the last answer is in, so the page never builds a queue.
//
// The exposure: rolling-shutter stripes need a short exposure (a fraction of one LED chip).
// The page asks the camera for the shortest one it allows (the Image Capture constraints
// exposureMode "manual" and exposureTime, in 100 us units) and says so when it cannot.
//
// Every frame's answer is kept in window.camvlpCapture.results (newest last), so that a test
// (or a curious user's console) can read what the page showed; window.camvlpCapture.idle
// says that no frame is in flight.
import {
  $, api, drawBasePlan, drawDot, fmtPosition, fmtSigma, forgetKey, saveKey, siteId, svg,
  takeKeyFromFragment,
} from "/static/common.js";

const TRAIL_LENGTH = 30;     // located fixes drawn as the trail
const RATE_WINDOW_MS = 5000; // frames per second over this window
const MAX_RESULTS = 5000;    // answers kept in window.camvlpCapture.results
const JPEG_QUALITY = 0.92;   // the stripes survive it
const MOTION_SMOOTHING = 0.2; // low-pass of the accelerometer: the hand's shakes average out
const MOTION_MAX_AGE_MS = 1000; // older readings are not sent

const state = {
  key: null, site: null, running: false, stream: null, track: null, imageCapture: null,
  seq: 0, newTrack: true, motion: null, trail: [], lastLocated: null, results: [],
  camera: null,
};
// idle: no frame of the page's in flight (after Stop, once the last answer is in)
window.camvlpCapture = { results: state.results, idle: true };

function setStatus(cls, text) {
  const el = $("status");
  el.className = `status ${cls}`;
  el.textContent = text;
}

function showError(message) {
  $("error").textContent = message || "";
  $("error").hidden = !message;
}

// --- gravity -------------------------------------------------------------------------------

function onMotion(event) {
  const a = event.accelerationIncludingGravity;
  if (!a || a.x === null || a.x === undefined) return;
  const m = state.motion;
  const k = MOTION_SMOOTHING;
  state.motion = m
    ? { x: m.x + k * (a.x - m.x), y: m.y + k * (a.y - m.y), z: m.z + k * (a.z - m.z) }
    : { x: a.x, y: a.y, z: a.z };
  state.motion.at = performance.now();
}

// Gravity in the rear camera's frame (OpenCV axes: x right and y down in the picture as the
// screen shows it, z out of the phone's back), from the accelerometer. The device's axes: x
// to the screen's right, y to its top, z out of the screen; accelerationIncludingGravity
// reads the reaction to gravity (up), so gravity is its opposite. The screen's rotation
// (screen.orientation.angle) turns the device's x and y into the picture's.
function cameraGravity() {
  const m = state.motion;
  if (!m || performance.now() - m.at > MOTION_MAX_AGE_MS) return null;
  const angle = ((screen.orientation && screen.orientation.angle) || window.orientation || 0);
  const th = (angle * Math.PI) / 180;
  const gx = -m.x, gy = -m.y, gz = -m.z;
  const sx = Math.cos(th) * gx - Math.sin(th) * gy;
  const sy = Math.sin(th) * gx + Math.cos(th) * gy;
  return [sx, -sy, -gz];
}

async function startMotion() {
  // iOS asks the user first, and only from a tap: this runs before any other await.
  const DME = window.DeviceMotionEvent;
  if (DME && typeof DME.requestPermission === "function") {
    try {
      if ((await DME.requestPermission()) !== "granted") {
        $("gravity-note").textContent = "Gravity: the motion sensor was refused; frames go " +
          "without it (four lights are then needed, or two with the track's help).";
        return;
      }
    } catch (e) { /* not from a tap: the listener below may still get readings */ }
  }
  window.addEventListener("devicemotion", onMotion);
}

function showGravity() {
  const g = cameraGravity();
  $("gravity-note").textContent = g
    ? `Gravity (camera frame): (${g.map((v) => v.toFixed(2)).join(", ")}) m/s², sent with ` +
      "each frame."
    : "Gravity: no motion sensor reading (this device or browser gives none): frames go " +
      "without it.";
}

// --- the camera ----------------------------------------------------------------------------

function cameraOfSize(width, height) {
  const cams = state.site.cameras;
  const chosen = $("camera").value;
  const fits = (n) => cams[n].image_width === width && cams[n].image_height === height;
  if (fits(chosen)) return chosen;
  return Object.keys(cams).find(fits) || null;
}

// Ask for the shortest exposure the camera allows; say what was set, or why nothing was.
async function setShortExposure(track) {
  const caps = track.getCapabilities ? track.getCapabilities() : {};
  const modes = caps.exposureMode || [];
  if (!modes.includes("manual") || !caps.exposureTime) {
    $("exposure-note").textContent = "Exposure: this browser or camera cannot set the " +
      "exposure time, so the camera picks its own: indoors usually several milliseconds, " +
      "which blurs the lights' stripes together. Few or no lights will decode: expect fixes " +
      "only where the lights are bright enough for the camera to choose a short exposure. " +
      "(Chrome on Android sets it on phones whose camera allows it.)";
    $("exposure-note").className = "note warn";
    return;
  }
  try {
    await track.applyConstraints({
      advanced: [{ exposureMode: "manual", exposureTime: caps.exposureTime.min }],
    });
    const set = track.getSettings().exposureTime;
    $("exposure-note").textContent = `Exposure: ${(set * 100).toFixed(0)} µs, the shortest ` +
      `this camera allows (${(caps.exposureTime.min * 100).toFixed(0)} µs).`;
    $("exposure-note").className = "note";
  } catch (error) {
    $("exposure-note").textContent = `Exposure: the camera refused a manual exposure ` +
      `(${error.message}); it picks its own, which may blur the stripes.`;
    $("exposure-note").className = "note warn";
  }
}

async function startCamera(event) {
  event.preventDefault();
  showError("");
  await startMotion();
  if (!window.isSecureContext || !navigator.mediaDevices) {
    showError("The browser gives the camera only to secure pages: open this page over " +
      "HTTPS (camvlp serve --tls-cert/--tls-key, or a reverse proxy).");
    return;
  }
  const cam = state.site.cameras[$("camera").value];
  try {
    state.stream = await navigator.mediaDevices.getUserMedia({
      audio: false,
      video: {
        facingMode: { ideal: "environment" },
        width: { ideal: cam.image_width },
        height: { ideal: cam.image_height },
      },
    });
  } catch (error) {
    showError(`No camera: ${error.message}`);
    return;
  }
  state.track = state.stream.getVideoTracks()[0];
  await setShortExposure(state.track);
  const video = $("preview");
  video.srcObject = state.stream;
  await video.play();
  const mode = $("mode").value;
  if (mode === "photos") {
    if (typeof window.ImageCapture !== "function") {
      showError("This browser cannot take photos from the stream (no ImageCapture): send " +
        "video frames instead.");
      stopCamera();
      return;
    }
    state.imageCapture = new ImageCapture(state.track);
  } else {
    const name = cameraOfSize(video.videoWidth, video.videoHeight);
    if (!name) {
      showError(`The camera gives ${video.videoWidth} x ${video.videoHeight} frames and the ` +
        "site has no camera of that size: add one (calibrated in this video mode) with PUT " +
        `/api/v1/sites/${siteId}/cameras/NAME, or turn the phone.`);
      stopCamera();
      return;
    }
    $("camera").value = name;
  }
  state.camera = $("camera").value;
  state.running = true;
  state.newTrack = true;
  $("start").hidden = true;
  $("stop").hidden = false;
  setStatus("live", "camera on");
  sendLoop();
}

function stopCamera() {
  state.running = false;
  if (state.stream) state.stream.getTracks().forEach((t) => t.stop());
  state.stream = state.track = state.imageCapture = null;
  $("start").hidden = false;
  $("stop").hidden = true;
  setStatus("off", "camera off");
}

// The next video frame, drawn into the hidden canvas at the camera's size; its capture time
// (ms on the page's clock) from requestVideoFrameCallback where the browser has it.
function grabFrame() {
  const video = $("preview");
  const canvas = $("grab");
  const cam = state.site.cameras[state.camera];
  return new Promise((resolve) => {
    const grab = (now, meta) => {
      canvas.width = cam.image_width;
      canvas.height = cam.image_height;
      canvas.getContext("2d").drawImage(video, 0, 0, canvas.width, canvas.height);
      const sizeOk = video.videoWidth === cam.image_width &&
        video.videoHeight === cam.image_height;
      resolve({ t: (meta && (meta.captureTime || meta.expectedDisplayTime)) || now, sizeOk });
    };
    if (video.requestVideoFrameCallback) video.requestVideoFrameCallback(grab);
    else requestAnimationFrame((now) => grab(now, null));
  });
}

async function nextPicture() {
  if (state.imageCapture) {
    const cam = state.site.cameras[state.camera];
    const blob = await state.imageCapture.takePhoto({
      imageWidth: cam.image_width, imageHeight: cam.image_height,
    });
    return { body: await blob.arrayBuffer(), type: blob.type || "image/jpeg",
      t: performance.now() };
  }
  const { t, sizeOk } = await grabFrame();
  if (!sizeOk) throw new Error("the camera's frame size changed: start again");
  const blob = await new Promise((resolve) => $("grab").toBlob(resolve, "image/jpeg",
    JPEG_QUALITY));
  return { body: await blob.arrayBuffer(), type: "image/jpeg", t };
}

async function sendLoop() {
  window.camvlpCapture.idle = false;
  try {
    await sendFrames();
  } finally {
    window.camvlpCapture.idle = true;
  }
}

async function sendFrames() {
  while (state.running) {
    let picture;
    try {
      picture = await nextPicture();
    } catch (error) {
      showError(`The camera: ${error.message}`);
      stopCamera();
      return;
    }
    if (!state.running) return;
    await sendFrame(picture);
  }
}

async function sendFrame({ body, type, t }) {
  const seq = ++state.seq;
  const params = new URLSearchParams({
    device: $("device").value || "phone", camera: state.camera, t: (t / 1000).toFixed(4),
  });
  const g = cameraGravity();
  if (g) params.set("gravity", g.map((v) => v.toFixed(5)).join(","));
  // a photo is located alone (a new track each time): when takePhoto's picture was taken is
  // not known well enough for the track's motion model
  if (state.newTrack || state.imageCapture) params.set("reset", "true");
  const entry = { seq, t: t / 1000, sent: performance.now() };
  try {
    const response = await api(state.key, `/frames?${params}`, {
      method: "POST", headers: { "Content-Type": type, "X-Frame-Seq": String(seq) }, body,
    });
    const answer = await response.json();
    state.newTrack = false;
    Object.assign(entry, {
      status: answer.status, located: answer.located, position: answer.position,
      position_sigma: answer.position_sigma, plan: answer.plan, fix_id: answer.fix_id,
      fixtures_used: answer.fixtures_used, fixtures: answer.fixtures, error: answer.error,
      frame: answer.frame, server_ms: answer.timing_ms.total,
    });
  } catch (error) {
    entry.status = error.status === 409 ? "dropped" : "error";
    entry.located = false;
    entry.error = error.message;
    entry.http = error.status;
    if (error.status === 401 || error.status === 403) {
      stopCamera();
      showKeyPanel(error.message);
    } else if (error.status === 429 || error.status === 503) {
      await new Promise((resolve) => setTimeout(resolve, 1000));
    } else if (error.status !== 409) {
      showError(`The service refused the frame: ${error.message}`);
      stopCamera();
    }
  }
  entry.latency_ms = performance.now() - entry.sent;
  entry.received = performance.now();
  state.results.push(entry);
  if (state.results.length > MAX_RESULTS) state.results.splice(0, state.results.length - MAX_RESULTS);
  if (entry.located) {
    state.lastLocated = entry;
    state.trail.push(entry.plan.position);
    if (state.trail.length > TRAIL_LENGTH) state.trail.shift();
  }
  showAnswer(entry);
}

// --- what the page shows -------------------------------------------------------------------

function median(values) {
  const v = [...values].sort((a, b) => a - b);
  return v.length ? v[Math.floor(v.length / 2)] : NaN;
}

function showAnswer(entry) {
  const units = state.site.units;
  $("st-status").textContent = entry.located
    ? entry.status
    : `${entry.status}: ${entry.error || "not located"}`;
  $("st-status").className = entry.located ? "" : "failed";
  const last = state.lastLocated;
  $("st-position").textContent = last ? `${fmtPosition(last.position)} ${units}` : "—";
  $("st-sigma").textContent = last && last.position_sigma
    ? `${fmtSigma(last.position_sigma)} ${units}` : "—";
  $("st-lights").textContent = last ? last.fixtures_used.join(", ") : "—";
  const now = performance.now();
  const recent = state.results.filter((r) => now - r.received <= RATE_WINDOW_MS);
  const since = Math.min(RATE_WINDOW_MS, now - (state.results.find(
    (r) => now - r.received <= RATE_WINDOW_MS) || entry).sent);
  const fps = recent.length / Math.max(since / 1000, 1e-3);
  $("st-fps").textContent = `${fps.toFixed(1)} sent, ` +
    `${(recent.filter((r) => r.located).length / Math.max(since / 1000, 1e-3)).toFixed(1)} located`;
  const lat = state.results.slice(-30).map((r) => r.latency_ms);
  $("st-latency").textContent = `${entry.latency_ms.toFixed(0)} ms (median of the last ` +
    `${lat.length}: ${median(lat).toFixed(0)} ms)`;
  const located = state.results.filter((r) => r.located).length;
  const dropped = state.results.filter((r) => r.status === "dropped").length;
  $("st-count").textContent = `${located} of ${state.results.length}` +
    (dropped ? ` (${dropped} dropped)` : "");
  showGravity();
  drawPlan();
}

function drawPlan() {
  const last = state.lastLocated;
  const used = new Set(last ? last.fixtures_used : []);
  const P = drawBasePlan($("plan"), state.site, state.trail, used);
  if (!last) return;
  const layer = svg("g", { class: "fixes" }, $("plan"));
  const pts = state.trail.map((p) => `${P.x(p[0])},${P.y(p[1])}`);
  svg("polyline", { class: "trail", points: pts.join(" ") }, layer);
  const [a, b] = last.plan.position;
  if (last.plan.sigma) {
    svg("ellipse", {
      class: "sigma", cx: P.x(a), cy: P.y(b),
      rx: 2 * last.plan.sigma[0] * P.s, ry: 2 * last.plan.sigma[1] * P.s,
    }, layer);
  }
  const stale = last !== state.results[state.results.length - 1];
  drawDot(layer, P, last.plan.position, last.plan.heading_deg,
    `${$("device").value || "phone"}${stale ? " (last fix)" : ""}`,
    { class: stale ? "fix latest stale" : "fix latest", "data-seq": last.seq });
}

// --- the site and its key ------------------------------------------------------------------

function showKeyPanel(message) {
  $("main").hidden = true;
  $("key-panel").hidden = false;
  $("key-error").hidden = !message;
  $("key-error").textContent = message || "";
}

async function openSite() {
  try {
    state.site = await (await api(state.key, "")).json();
  } catch (error) {
    if (error.status === 401 || error.status === 403 || error.status === 404) forgetKey();
    showKeyPanel(error.message);
    return;
  }
  $("key-panel").hidden = true;
  $("main").hidden = false;
  $("site-name").textContent = state.site.name;
  $("site-id").textContent = `site ${siteId} · camera`;
  $("site-link").href = `/sites/${siteId}`;
  document.title = `camvlp · ${state.site.name} · camera`;
  $("camera").replaceChildren(...Object.entries(state.site.cameras).map(([name, cam]) => {
    const option = document.createElement("option");
    option.value = name;
    option.textContent = `${name} (${cam.image_width} x ${cam.image_height})`;
    return option;
  }));
  if (!window.isSecureContext) {
    $("secure-note").textContent = "This page is not a secure context (plain HTTP on " +
      "another machine): the browser will not give it the camera. Open it over HTTPS.";
    $("secure-note").hidden = false;
  }
  drawPlan();
}

function deviceName() {
  let name = sessionStorage.getItem("camvlp.device");
  if (!name) {
    name = `phone-${Math.random().toString(16).slice(2, 6)}`;
    sessionStorage.setItem("camvlp.device", name);
  }
  return name;
}

$("key-form").addEventListener("submit", (event) => {
  event.preventDefault();
  state.key = $("key-input").value.trim();
  saveKey(state.key);
  openSite();
});
$("capture-form").addEventListener("submit", startCamera);
$("stop").addEventListener("click", stopCamera);
$("device").value = deviceName();
$("device").addEventListener("change", () => {
  sessionStorage.setItem("camvlp.device", $("device").value);
  state.newTrack = true;
});

state.key = takeKeyFromFragment();
if (!Number.isInteger(siteId) || siteId <= 0) showKeyPanel("no site in this address");
else if (state.key) openSite();
else showKeyPanel("");
