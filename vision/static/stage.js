// mimic's live page: the performer's camera (when the server asks this page for it), the
// avatar in 3D (three.js, vendored), the state, and a strip of the last 20 s of actions.
// Protocol (vision/_stage.py): JSON text messages from the server (hello, skeleton, pose,
// state, note; options and plan with mimic play), the performer's picture as binary JPEG;
// from the page, camera frames as binary (float64 little-endian page time in ms, then a
// JPEG) and JSON (camera-error, stats; choose and sketch with mimic play).
import * as THREE from "./three.module.min.js";

const $ = (id) => document.getElementById(id);
const MAX_SIDE = 640; // the long side of a frame sent to the server
const IN_FLIGHT = 2; // frames sent and not yet answered by a pose: more are not sent
const STRIP_S = 20;
const LATENCY_WINDOW_MS = 10000;

const page = {
  role: "", frames: 0, latencies: [], sentTimes: [], acked: -Infinity, inflight: [],
  history: [], closed: false, all: [],
};
window.mimic = page; // for tests and the curious: page.joints() lists projected joints

// --- notes ----------------------------------------------------------------------------
function note(text, level = "info") {
  const div = document.createElement("div");
  div.className = level;
  div.textContent = text;
  $("notes").prepend(div);
  while ($("notes").childElementCount > 6) $("notes").lastChild.remove();
}

// --- the 3D stage -----------------------------------------------------------------------
const holder = $("stage3d");
// A browser without a GPU draws WebGL on the processor (SwiftShader, llvmpipe), on the
// cores that also encode the camera's frames and run the loop: there the avatar is drawn
// without multisampling, at most 15 times a second, and the camera's frames go first.
function softwareGL() {
  const gl = document.createElement("canvas").getContext("webgl");
  if (!gl) return false;
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
  const lose = gl.getExtension("WEBGL_lose_context");
  if (lose) lose.loseContext(); // (a probe: browsers keep few contexts)
  return /swiftshader|llvmpipe|softpipe|software/i.test(name);
}
page.softwareGL = softwareGL();
const DRAW_MS = page.softwareGL ? 66 : 30; // (the poses come at 30 a second)
const renderer = new THREE.WebGLRenderer({
  antialias: !page.softwareGL, preserveDrawingBuffer: true,
});
renderer.setPixelRatio(page.softwareGL ? 1 : window.devicePixelRatio || 1);
holder.prepend(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x20242c);
const camera = new THREE.PerspectiveCamera(40, 4 / 3, 0.05, 100);
scene.add(new THREE.HemisphereLight(0xdde6ff, 0x303030, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(2, 5, 4);
scene.add(sun);
// the floor: a plane tiled in 1 m squares (a texture: GL lines are drawn unevenly by
// software renderers), kept under the avatar so that it never ends
const tile = document.createElement("canvas");
tile.width = tile.height = 128;
const paint = tile.getContext("2d");
paint.fillStyle = "#3a3f4b";
paint.fillRect(0, 0, 128, 128);
paint.strokeStyle = "#8a90a0";
paint.lineWidth = 3;
paint.strokeRect(0, 0, 128, 128);
const tiles = new THREE.CanvasTexture(tile);
tiles.wrapS = tiles.wrapT = THREE.RepeatWrapping;
tiles.repeat.set(60, 60);
tiles.anisotropy = 8;
tiles.colorSpace = THREE.SRGBColorSpace;
const grid = new THREE.Mesh(new THREE.PlaneGeometry(60, 60), new THREE.MeshStandardMaterial({ map: tiles, roughness: 0.9 }));
grid.rotation.x = -Math.PI / 2;
scene.add(grid);
scene.fog = new THREE.Fog(0x20242c, 12, 30);
const skin = new THREE.MeshStandardMaterial({ color: 0xff9628, roughness: 0.55 });
let joints = []; // THREE.Group per joint
let from = null, to = null, poseAt = 0, poseFor = 33;
const look = new THREE.Vector3(0, 1, 0);

function bone(group, offset, radius) {
  const v = new THREE.Vector3(...offset);
  const length = v.length();
  if (length < 1e-3) return;
  const mesh = new THREE.Mesh(new THREE.CapsuleGeometry(radius, length, 4, 10), skin);
  mesh.position.copy(v).multiplyScalar(0.5);
  mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), v.normalize());
  group.add(mesh);
}

function buildAvatar(sk) {
  for (const j of joints) if (j.parent === scene) scene.remove(j);
  joints = sk.names.map(() => new THREE.Group());
  sk.parents.forEach((p, j) => {
    joints[j].position.fromArray(sk.offsets[j]);
    (p < 0 ? scene : joints[p]).add(joints[j]);
    if (p >= 0) bone(joints[p], sk.offsets[j], /spine|back|neck|hips|thigh|upleg/i.test(sk.names[p]) ? 0.06 : 0.04);
  });
  sk.end_parents.forEach((p, e) => {
    const head = /head/i.test(sk.names[p]);
    bone(joints[p], sk.end_offsets[e], head ? 0.09 : 0.035);
  });
  from = to = null;
}

function toPose(message) {
  return {
    t: message.t,
    root: new THREE.Vector3(...message.root),
    q: message.q.map(([w, x, y, z]) => new THREE.Quaternion(x, y, z, w)),
  };
}

function onPose(message) {
  if (!joints.length || message.q.length !== joints.length) return;
  const next = toPose(message);
  const now = performance.now();
  if (to) {
    from = shown(now);
    poseFor = Math.min(250, Math.max(10, (next.t - to.t) * 1000));
  }
  to = next;
  poseAt = now;
  if (message.ts != null) {
    page.acked = Math.max(page.acked, message.ts);
    page.latencies.push([now, now - message.ts]);
    if (page.all.length < 200000) page.all.push(now - message.ts); // the run's (bench_vision)
  }
}

// the pose at time `now`: from the last shown towards the newest, over the time between poses
function shown(now) {
  if (!from) return { t: to.t, root: to.root.clone(), q: to.q.map((q) => q.clone()) };
  const a = Math.min(1, (now - poseAt) / poseFor);
  return {
    t: to.t,
    root: from.root.clone().lerp(to.root, a),
    q: to.q.map((q, j) => new THREE.Quaternion().slerpQuaternions(from.q[j], q, a)),
  };
}

let rendered = 0;
function render(now) {
  requestAnimationFrame(render);
  // at most about 30 frames a second (15 in software: DRAW_MS); none while held
  // (page.held: a test compares a screenshot with the joints' places)
  if (now - rendered < DRAW_MS || page.held) return;
  rendered = now;
  const w = holder.clientWidth, h = holder.clientHeight;
  if (renderer.domElement.width !== Math.round(w * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  if (to && joints.length) {
    const p = shown(performance.now());
    joints[0].position.copy(p.root);
    p.q.forEach((q, j) => joints[j].quaternion.copy(q));
    look.lerp(new THREE.Vector3(p.root.x, 0.9, p.root.z), 0.08); // the camera follows
  }
  camera.position.set(look.x, look.y + 1.6, look.z + 5.2);
  camera.lookAt(look);
  grid.position.set(Math.round(look.x), 0, Math.round(look.z)); // an endless floor
  renderer.render(scene, camera);
}
requestAnimationFrame(render);

// where each joint is on the page (CSS pixels): the tests look for the avatar there
page.joints = () => {
  const rect = renderer.domElement.getBoundingClientRect();
  scene.updateMatrixWorld();
  return joints.map((j) => {
    const v = j.getWorldPosition(new THREE.Vector3()).project(camera);
    return [rect.left + ((v.x + 1) / 2) * rect.width, rect.top + ((1 - v.y) / 2) * rect.height];
  });
};

// --- the state and the strip ------------------------------------------------------------
function hue(name) {
  let h = 0;
  for (const c of name || "") h = (h * 31 + c.charCodeAt(0)) % 360;
  return `hsl(${h}, 60%, 50%)`;
}

function onState(s) {
  if (page.role === "camera" && s.camera && s.camera !== "receiving frames") {
    $("role").textContent = `your camera: ${s.camera}`;
  } else if (page.role === "camera") {
    $("role").textContent = "your camera drives the avatar";
  }
  $("action").textContent = s.action ?? "-";
  $("performer").textContent = s.performer ?? (s.why ? `(${s.why})` : "-");
  $("cost").textContent = s.cost == null ? "-" : s.cost.toFixed(3);
  $("latency").textContent = s.latency_ms == null ? "-" : s.latency_ms.toFixed(1);
  $("time").textContent = `${(s.t ?? 0).toFixed(1)} s`;
  if (s.action != null) {
    const last = page.history[page.history.length - 1];
    if (!last || last.t !== s.t) page.history.push({ t: s.t, you: s.performer, avatar: s.action });
  }
  drawStrip();
}

function drawStrip() {
  const c = $("strip");
  c.width = c.clientWidth;
  c.height = c.clientHeight;
  const g = c.getContext("2d");
  g.fillStyle = "#15171b";
  g.fillRect(0, 0, c.width, c.height);
  const h = page.history;
  if (!h.length) return;
  const end = h[h.length - 1].t, x0 = 70, span = c.width - x0;
  const x = (t) => x0 + (span * (t - (end - STRIP_S))) / STRIP_S;
  g.font = "12px sans-serif";
  ["you", "avatar"].forEach((row, r) => {
    const y = 6 + r * 30;
    g.fillStyle = "#aaa";
    g.fillText(row, 6, y + 16);
    const runs = []; // [action, left, right]: the row's runs of one action
    for (let i = 0; i < h.length; i++) {
      const a = h[i], b = h[i + 1];
      if (a.t < end - STRIP_S - 1 || !a[row]) continue;
      const left = Math.max(x0, x(a.t)), right = b ? x(b.t) : c.width;
      const last = runs[runs.length - 1];
      if (last && last[0] === a[row] && Math.abs(last[2] - left) < 1) last[2] = right;
      else runs.push([a[row], left, right]);
    }
    for (const [name, left, right] of runs) {
      g.fillStyle = hue(name);
      g.fillRect(left, y, right - left + 0.5, 24);
    }
    g.fillStyle = "#fff";
    for (const [name, left, right] of runs) {
      if (g.measureText(name).width + 6 < right - left) g.fillText(name, left + 3, y + 16);
    }
  });
  while (h.length && h[0].t < end - STRIP_S - 2) h.shift();
}

// --- latency and rate -------------------------------------------------------------------
function percentile(sorted, p) {
  return sorted[Math.min(sorted.length - 1, Math.floor((p / 100) * sorted.length))];
}

setInterval(() => {
  const now = performance.now();
  page.latencies = page.latencies.filter(([at]) => now - at < LATENCY_WINDOW_MS);
  page.sentTimes = page.sentTimes.filter((at) => now - at < LATENCY_WINDOW_MS);
  const ms = page.latencies.map(([, v]) => v).sort((a, b) => a - b);
  page.firstSent ??= page.sentTimes[0];
  const span = Math.min(LATENCY_WINDOW_MS, now - (page.firstSent ?? now)) / 1000;
  const fps = span > 0.5 ? page.sentTimes.length / span : 0;
  page.stats = {
    p50_ms: ms.length ? percentile(ms, 50) : null, p99_ms: ms.length ? percentile(ms, 99) : null,
    fps, frames: page.frames, n: ms.length,
  };
  $("p50").textContent = ms.length ? page.stats.p50_ms.toFixed(0) : "-";
  $("p99").textContent = ms.length ? page.stats.p99_ms.toFixed(0) : "-";
  $("fps").textContent = page.role === "camera" ? fps.toFixed(1) : "-";
  if (page.role === "camera" && ws.readyState === 1) ws.send(JSON.stringify({ type: "stats", ...page.stats }));
}, 1000);

// --- the camera -------------------------------------------------------------------------
const video = $("camera");
const grab = document.createElement("canvas");

async function startCamera() {
  let stream;
  try {
    if (!navigator.mediaDevices?.getUserMedia) {
      throw Object.assign(new Error("this browser gives pages no camera (a page not on localhost?)"), { name: "NotSupportedError" });
    }
    stream = await navigator.mediaDevices.getUserMedia({ video: { width: { ideal: 640 }, height: { ideal: 480 } }, audio: false });
  } catch (e) {
    note(`the camera did not open: ${e.name}: ${e.message}`, "error");
    if (ws.readyState === 1) ws.send(JSON.stringify({ type: "camera-error", name: e.name, message: e.message }));
    return;
  }
  video.srcObject = stream;
  await video.play();
  note("the camera is on: step back so that your whole body is in view");
  if ("requestVideoFrameCallback" in video) {
    const each = () => { sendFrame(); video.requestVideoFrameCallback(each); };
    video.requestVideoFrameCallback(each);
  } else {
    setInterval(sendFrame, 33);
  }
}

function sendFrame() {
  const now = performance.now();
  if (ws.readyState !== 1 || !video.videoWidth) return;
  // frames the loop has not answered (older than 1 s: given up on) hold back the next
  page.inflight = page.inflight.filter((s) => s > page.acked && now - s < 1000);
  if (page.inflight.length >= IN_FLIGHT || ws.bufferedAmount > 1 << 20) return;
  const scale = Math.min(1, MAX_SIDE / Math.max(video.videoWidth, video.videoHeight));
  grab.width = Math.round(video.videoWidth * scale);
  grab.height = Math.round(video.videoHeight * scale);
  grab.getContext("2d").drawImage(video, 0, 0, grab.width, grab.height);
  page.inflight.push(now);
  grab.toBlob(async (jpeg) => {
    if (!jpeg || ws.readyState !== 1) return;
    const head = new ArrayBuffer(8);
    new DataView(head).setFloat64(0, now, true);
    ws.send(await new Blob([head, jpeg]).arrayBuffer());
    page.frames += 1;
    page.sentTimes.push(performance.now());
  }, "image/jpeg", 0.8);
}

// --- choice and sketch (mimic play) --------------------------------------------------------
let offerId = -1;
let hoverPath = null, drawnLine = null, planLine = null;

function floorLine(points, color, y = 0.01) {
  const geometry = new THREE.BufferGeometry().setFromPoints(points.map(([x, z]) => new THREE.Vector3(x, y, z)));
  const line = new THREE.Line(geometry, new THREE.LineBasicMaterial({ color }));
  scene.add(line);
  return line;
}

function drop(line) {
  if (line) { scene.remove(line); line.geometry.dispose(); }
  return null;
}

function onOptions(m) {
  const box = $("choices");
  box.replaceChildren();
  hoverPath = drop(hoverPath);
  offerId = m.id;
  if (m.id < 0) return;
  m.options.forEach((o, i) => {
    const button = document.createElement("button");
    const canvas = document.createElement("canvas");
    canvas.width = canvas.height = 120;
    canvas.preview = o.preview;
    button.append(canvas, document.createTextNode(`${i + 1}. ${o.label}`));
    button.onclick = () => {
      if (ws.readyState === 1) ws.send(JSON.stringify({ type: "choose", offer: offerId, option: i }));
      page.chosen = (page.chosen || 0) + 1;
    };
    button.onmouseenter = () => { hoverPath = drop(hoverPath); hoverPath = floorLine(o.path, 0x7fd1ff); };
    button.onmouseleave = () => { hoverPath = drop(hoverPath); };
    box.append(button);
  });
  page.offers = (page.offers || 0) + 1;
}

// each option's preview: its motion as a stick figure, looping
let previewFrame = 0;
setInterval(() => {
  previewFrame += 1;
  for (const canvas of document.querySelectorAll("#choices canvas")) {
    const { bones, poses } = canvas.preview;
    const pose = poses[previewFrame % poses.length];
    const g = canvas.getContext("2d");
    g.clearRect(0, 0, canvas.width, canvas.height);
    g.strokeStyle = "#ff9628";
    g.lineWidth = 3;
    g.lineCap = "round";
    const px = ([x, y]) => [canvas.width / 2 + x * 55, canvas.height - 8 - y * 55];
    g.beginPath();
    for (const [a, b] of bones) {
      g.moveTo(...px(pose[a]));
      g.lineTo(...px(pose[b]));
    }
    g.stroke();
  }
}, 80);

// drawing a path on the floor: a drag on the 3D view, each point where the ray meets y = 0
const floor = new THREE.Plane(new THREE.Vector3(0, 1, 0), 0);
const ray = new THREE.Raycaster();
let drawing = null;

function floorPoint(event) {
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1, -((event.clientY - rect.top) / rect.height) * 2 + 1);
  ray.setFromCamera(ndc, camera);
  const hit = ray.ray.intersectPlane(floor, new THREE.Vector3());
  return hit ? [hit.x, hit.z] : null;
}

renderer.domElement.addEventListener("pointerdown", (event) => {
  if (!page.controls || event.button !== 0) return;
  const p = floorPoint(event);
  if (!p) return;
  drawing = [p];
  drawnLine = drop(drawnLine);
  renderer.domElement.setPointerCapture(event.pointerId);
});
renderer.domElement.addEventListener("pointermove", (event) => {
  if (!drawing) return;
  const p = floorPoint(event);
  const last = drawing[drawing.length - 1];
  if (p && Math.hypot(p[0] - last[0], p[1] - last[1]) > 0.05) {
    drawing.push(p);
    drawnLine = drop(drawnLine);
    drawnLine = floorLine(drawing, 0xffffff, 0.02);
  }
});
renderer.domElement.addEventListener("pointerup", () => {
  if (!drawing) return;
  const points = drawing;
  drawing = null;
  if (points.length >= 2 && ws.readyState === 1) {
    ws.send(JSON.stringify({ type: "sketch", points }));
    page.sketches = (page.sketches || 0) + 1;
  }
});

function onPlan(m) {
  planLine = drop(planLine);
  planLine = floorLine(m.path, m.followed ? 0x6be38a : 0xff7b72, 0.015);
  page.plans = (page.plans || 0) + 1;
  note(m.followed ? "the avatar follows your path" : "the avatar follows your path as far as it can", m.followed ? "info" : "error");
}

// --- the connection ---------------------------------------------------------------------
const ws = new WebSocket(`ws://${location.host}/ws`);
ws.binaryType = "arraybuffer";
let picture = null;

ws.onmessage = (event) => {
  if (typeof event.data !== "string") {
    const old = picture;
    picture = URL.createObjectURL(new Blob([event.data], { type: "image/jpeg" }));
    $("you").src = picture;
    if (old) URL.revokeObjectURL(old);
    return;
  }
  const m = JSON.parse(event.data);
  if (m.type === "hello") {
    page.role = m.role;
    $("role").textContent = m.role === "camera" ? "your camera drives the avatar" : "watching the run";
    if (m.skeleton) buildAvatar(m.skeleton);
    if (m.note) note(m.note, "info");
    if (m.role === "camera") startCamera();
    page.controls = !!m.controls;
    $("controls").hidden = !m.controls;
    if (m.controls) {
      $("role").textContent = "you steer the avatar";
      document.querySelector(".pane").hidden = true; // no performer: the avatar takes the row
    }
  } else if (m.type === "skeleton") {
    buildAvatar(m.skeleton);
  } else if (m.type === "pose") {
    onPose(m);
  } else if (m.type === "state") {
    onState(m);
  } else if (m.type === "options") {
    onOptions(m);
  } else if (m.type === "plan") {
    onPlan(m);
  } else if (m.type === "note") {
    note(m.text, m.level);
  }
};

ws.onclose = (event) => {
  page.closed = true;
  const why = event.code === 1009 ? "a frame was too big for the server" : event.reason || "the run ended";
  note(`disconnected (${event.code}): ${why}`, event.code === 1000 || event.code === 1001 ? "info" : "error");
  $("role").textContent = "the run is over";
};
