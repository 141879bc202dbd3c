// The web display: a WebDisplay (the display's store, driver and denoiser,
// in WebAssembly) fed the WebSocket's bytes and the page's input, drawing
// into a canvas. The link's fragment (never sent to the server) carries the
// options: #token=…&view=…&driver=quadtree|splat&denoise=off&width=…&height=…
// &density=…&max-density=… (samples per pixel asked for, and the most a
// still view raises it to)&neighbours=1 (a replayed site fills the pixels a
// view's beams leave without a ray from the beams next to theirs).
import init, { WebDisplay } from "./holodeck_web.js";

const params = new URLSearchParams(location.hash.slice(1));
let token = params.get("token") ?? sessionStorage.getItem("holodeck-token") ?? "";
const readOnly = params.get("read-only") === "1";
const width = Math.max(16, Math.min(4096, Number(params.get("width")) || 640));
const height = Math.max(16, Math.min(4096, Number(params.get("height")) || 480));

const canvas = document.getElementById("view");
const statusBox = document.getElementById("status");
const said = document.getElementById("said");
const line = document.getElementById("line");
const joinForm = document.getElementById("join");
const ctx = canvas.getContext("2d");
canvas.width = width;
canvas.height = height;

const now = () => performance.now() / 1000;
const log = [];
function say(text) {
  if (!text) return;
  log.push(text);
  said.textContent = text;
}

await init({ module_or_path: new URL("holodeck_web_bg.wasm", import.meta.url) });
let display;
try {
  const density = Number(params.get("density")) || 1;
  display = new WebDisplay(params.get("view") ?? "", width, height, params.get("driver") ?? "quadtree",
    params.get("denoise") !== "off", density, Math.max(density, Number(params.get("max-density")) || 1024));
} catch (e) {
  statusBox.textContent = `the display cannot start: ${e.message}`;
  throw e;
}

let socket = null;
let refused = false;
let backoff = 0.5;
// Nothing is drawn before something arrives (the first frames would run
// before the browser has optimized the display's code).
let dirty = false;
let held = null;
let frameMs = 0;
let lastDraw = 0;
let frames = 0;
let connects = 0;
let bytesIn = 0;
// Where the page's time goes (milliseconds): taking the server's bytes, drawing.
const timing = { receive: 0, draw: 0, messages: 0, ready: 0, opened: 0, first: 0, last: 0 };

// What the page sent, first messages only (scripts replay a page's greeting).
const sentLog = [];
function flush() {
  const out = display.take_output();
  if (out.length > 0 && socket && socket.readyState === WebSocket.OPEN) {
    if (sentLog.length < 4) sentLog.push(out.slice());
    socket.send(out);
  }
}

function connect() {
  if (!token) {
    joinForm.hidden = false;
    statusBox.textContent = "an access token is needed to join";
    return;
  }
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  timing.connect ||= performance.now();
  socket = new WebSocket(`${scheme}//${location.host}/ws`);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => {
    timing.opened ||= performance.now();
    connects += 1;
    display.hello(token, readOnly);
    flush();
  };
  socket.onmessage = (event) => {
    bytesIn += event.data.byteLength;
    const t = performance.now();
    timing.first ||= t;
    timing.last = t;
    try {
      display.receive(new Uint8Array(event.data), now());
      timing.receive += performance.now() - t;
      timing.messages += 1;
      backoff = 0.5;
    } catch (e) {
      refused = true;
      say(e.message);
      if (/token/.test(e.message)) joinForm.hidden = false;
      socket.close();
    }
    dirty = true;
    flush();
  };
  socket.onclose = () => {
    if (refused) {
      statusBox.textContent = "not connected";
      return;
    }
    // The server restarted or the network dropped: keep the picture, try again.
    display.reconnect();
    statusBox.textContent = `connection lost: reconnecting in ${backoff} s`;
    setTimeout(connect, backoff * 1000);
    backoff = Math.min(backoff * 2, 8);
  };
}

// A static site (`holodeck export web`): the file's index beside the page,
// and its beams fetched by byte range, applied in the order asked.
let replay = false;
let fetched = Promise.resolve();
let ranged = 0;
const wholeChunks = new Map();
async function openSite() {
  let response;
  try {
    response = await fetch("holodeck.idx");
  } catch {
    return false;
  }
  if (!response.ok) return false;
  display.set_neighbours(params.get("neighbours") === "1");
  display.open_site(new Uint8Array(await response.arrayBuffer()), now());
  replay = true;
  return true;
}
async function getRange(chunk, start, end) {
  const name = `beams-${String(chunk).padStart(4, "0")}.bin`;
  if (wholeChunks.has(name)) return (await wholeChunks.get(name)).subarray(start, end);
  const response = await fetch(name, { headers: { Range: `bytes=${start}-${end - 1}` } });
  if (!response.ok) throw new Error(`${name}: HTTP ${response.status}`);
  if (response.status === 206) {
    ranged += 1;
    const b = new Uint8Array(await response.arrayBuffer());
    bytesIn += b.length;
    return b;
  }
  // The host ignores byte ranges: keep the few whole chunks lately used.
  const whole = response.arrayBuffer().then((b) => {
    bytesIn += b.byteLength;
    return new Uint8Array(b);
  });
  wholeChunks.set(name, whole);
  if (wholeChunks.size > 8) wholeChunks.delete(wholeChunks.keys().next().value);
  return (await whole).subarray(start, end);
}
function startFetches() {
  const f = display.take_fetches();
  for (let i = 0; i < f.length; i += 3) {
    const [chunk, start, end] = [f[i], f[i + 1], f[i + 2]];
    const bytes = getRange(chunk, start, end).catch((e) => {
      say(`fetching beams: ${e.message}`);
      return null;
    });
    fetched = fetched.then(async () => {
      const b = await bytes;
      try {
        display.add_fetched(chunk, start, b ?? new Uint8Array(0), b === null, now());
      } catch (e) {
        say(e.message);
      }
      dirty = true;
    });
  }
}

function draw() {
  const start = performance.now();
  const rgba = display.frame();
  ctx.putImageData(new ImageData(new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, rgba.length), width, height), 0, 0);
  frameMs = performance.now() - start;
  timing.draw += frameMs;
  lastDraw = now();
  frames += 1;
  // A GPU driver's frame still on its way from the GPU: the next animation frame draws it.
  dirty = display.frame_pending();
}

function loop() {
  try {
    display.tick(now());
  } catch (e) {
    say(e.message);
  }
  flush();
  if (replay) startFetches();
  // While moving, every frame. While still, new samples at most ten times a
  // second, drawing at most a fifth of the time; while a view's stored rays
  // stream in, a twentieth (the browser reads the socket only as fast as
  // the page takes its messages, so time spent drawing slows the stream).
  const share = display.transfers() > 0 ? 20 : 5;
  const pending = display.frame_pending();
  if (held !== null || pending || (dirty && now() - lastDraw >= Math.max(0.1, (share * frameMs) / 1000))) draw();
  const notices = display.notices();
  if (notices) say(notices);
  requestAnimationFrame(loop);
}

setInterval(() => {
  if (display.is_open()) statusBox.textContent = display.status(frameMs);
}, 250);
// The status line at once when the display opens (tests and users read it).
statusBox.textContent = "connecting…";

// Pixel of the canvas under a pointer event.
function pixel(event) {
  const r = canvas.getBoundingClientRect();
  return [(event.clientX - r.left) * width / r.width, (event.clientY - r.top) * height / r.height];
}

// Mouse and touch through pointer events: the mouse's buttons as the
// window's; one finger forward, two back, a pinch turns.
const touches = new Map();
let pinch = null;
function press(button, shift, at) {
  if (held !== null) display.release(held, now());
  held = button;
  display.press(button, shift, at[0], at[1]);
  dirty = true;
}
function release() {
  if (held === null) return;
  display.release(held, now());
  held = null;
  dirty = true;
  flush();
}
canvas.addEventListener("contextmenu", (e) => e.preventDefault());
canvas.addEventListener("pointerdown", (e) => {
  canvas.focus();
  try {
    canvas.setPointerCapture(e.pointerId);
  } catch {
    // A pointer the browser no longer tracks: the motion goes on without capture.
  }
  e.preventDefault();
  if (e.pointerType === "touch") {
    touches.set(e.pointerId, pixel(e));
    const pts = [...touches.values()];
    if (pts.length === 1) press(0, false, pts[0]);
    if (pts.length === 2) {
      pinch = Math.hypot(pts[0][0] - pts[1][0], pts[0][1] - pts[1][1]);
      press(2, false, [(pts[0][0] + pts[1][0]) / 2, (pts[0][1] + pts[1][1]) / 2]);
    }
    return;
  }
  press(e.button, e.shiftKey, pixel(e));
});
canvas.addEventListener("pointermove", (e) => {
  const at = pixel(e);
  if (e.pointerType === "touch" && touches.has(e.pointerId)) {
    touches.set(e.pointerId, at);
    const pts = [...touches.values()];
    if (pts.length === 2) {
      const mid = [(pts[0][0] + pts[1][0]) / 2, (pts[0][1] + pts[1][1]) / 2];
      const spread = Math.hypot(pts[0][0] - pts[1][0], pts[0][1] - pts[1][1]);
      // Fingers spreading or closing: a pinch turns toward their middle.
      if (pinch !== null && held !== 1 && Math.abs(spread - pinch) > 0.15 * pinch) press(1, false, mid);
      display.pointer(mid[0], mid[1]);
      return;
    }
  }
  display.pointer(at[0], at[1]);
});
function lift(e) {
  if (e.pointerType === "touch") {
    touches.delete(e.pointerId);
    if (touches.size > 0) return;
    pinch = null;
  }
  release();
}
canvas.addEventListener("pointerup", lift);
canvas.addEventListener("pointercancel", lift);

document.addEventListener("keydown", (e) => {
  if (e.target === line || e.target === document.getElementById("token")) return;
  if (e.key === "Shift" || e.key === "Control") return;
  try {
    const answer = display.key(e.key, e.ctrlKey, now());
    if (answer) say(answer);
    if (e.ctrlKey && (e.key === "r" || e.key === "l")) e.preventDefault();
  } catch (err) {
    say(err.message);
  }
  dirty = true;
  flush();
});

document.getElementById("command").addEventListener("submit", (e) => {
  e.preventDefault();
  try {
    const answer = display.line(line.value, now());
    say(answer || `${line.value.trim()}: done`);
  } catch (err) {
    say(err.message);
  }
  dirty = true;
  flush();
});

joinForm.addEventListener("submit", (e) => {
  e.preventDefault();
  token = document.getElementById("token").value.trim();
  sessionStorage.setItem("holodeck-token", token);
  joinForm.hidden = true;
  refused = false;
  display.reconnect();
  connect();
});

document.getElementById("save").addEventListener("click", () => {
  draw();
  canvas.toBlob((blob) => {
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = "holodeck.png";
    a.click();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }, "image/png");
});

// For scripts and tests: what the page shows, read back.
window.holodeck = {
  where: () => display.view_line(),
  line: (text) => { const a = display.line(text, now()); dirty = true; flush(); return a; },
  // The frame in linear radiance (a GPU driver's: once it is back from the GPU).
  picture: async () => {
    let data = display.picture();
    while (display.frame_pending()) {
      await new Promise((done) => setTimeout(done, 5));
      data = display.picture();
    }
    return { width, height, data: Array.from(data) };
  },
  pixels: () => Array.from(ctx.getImageData(0, 0, width, height).data),
  transfers: () => display.transfers(),
  samples: () => display.samples(),
  open: () => display.is_open(),
  status: () => statusBox.textContent,
  frames: () => frames,
  connects: () => connects,
  replay: () => replay,
  driver: () => display.driver(),
  bytes: () => bytesIn,
  sentLog: () => sentLog,
  timing: () => ({ ...timing }),
  // Draws `n` frames back to back: the mean milliseconds of the display's
  // frame (drawing and tone mapping in WebAssembly) and of the whole draw.
  // Frames drawn back to back: `render_ms`, the display's drawing of a
  // frame afresh (its driver and denoiser, in WebAssembly); `draw_ms`, a
  // whole draw of the page (tone map and canvas too, the denoised frame kept).
  benchFrames: (n) => {
    const render = display.bench_render(n);
    const start = performance.now();
    for (let i = 0; i < n; i += 1) draw();
    return { render_ms: render, draw_ms: (performance.now() - start) / n };
  },
  ranged: () => ranged,
  log,
};

timing.ready = performance.now();
// Beside a site's index the page replays the file; otherwise it joins the server that served it.
if (!(await openSite())) connect();
requestAnimationFrame(loop);
