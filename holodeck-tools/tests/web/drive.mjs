// Drives Debian's chromium, headless, for the web display's tests: one JSON
// request per line on standard input, one JSON answer per line on standard
// output ({"ok": value} or {"error": "..."}). The browser is the system's
// (CHROMIUM, default /usr/bin/chromium); nothing is downloaded.
//
// Requests: {"op":"open","url":U} · {"op":"eval","js":EXPR} (the value of
// EXPR, awaited) · {"op":"wait","js":EXPR,"timeout":MS} (until EXPR is
// truthy; its value) · {"op":"mouse","action":"move"|"down"|"up","x":X,"y":Y,
// "button":"left"|"middle"|"right"} (X, Y in canvas pixels) · {"op":"hold","ms":MS}
// · {"op":"type","selector":S,"text":T,"enter":true} · {"op":"key","key":K}
// · {"op":"screenshot","path":P} · {"op":"backend"} · {"op":"close"}
// · {"op":"download","selector":S,"path":P} (click S, save the download at P)
// · {"op":"site","dir":D,"origin":O} (O's pages are D's files, as a static
// host serves them, byte ranges included: no server process at all).
import { readFile } from "node:fs/promises";
import { join, normalize } from "node:path";
import { createInterface } from "node:readline";
import { chromium } from "playwright-core";

const server = await chromium.launchServer({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: [
    "--headless=new", "--no-sandbox", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-quic", "--enable-unsafe-swiftshader",
    // The tests' servers present self-signed certificates made for them.
    "--ignore-certificate-errors",
    // More flags for one test (a browser without WebGL, say).
    ...(process.env.CHROMIUM_FLAGS ?? "").split(" ").filter((f) => f),
  ],
});
// The test ends the browser's process group by this PID, whatever becomes of this driver.
process.stdout.write(JSON.stringify({ browser_pid: server.process().pid }) + "\n");
const browser = await chromium.connect(server.wsEndpoint());
const page = await browser.newPage({ viewport: { width: 1280, height: 900 } });
const console_lines = [];
page.on("console", (m) => console_lines.push(m.text()));
page.on("pageerror", (e) => console_lines.push(`page error: ${e.message}`));

const TYPES = { ".html": "text/html", ".js": "text/javascript", ".wasm": "application/wasm" };
const served = { requests: 0, ranged: 0 };
async function serveSite(dir, origin) {
  await page.route(`${origin}/**`, async (route) => {
    const request = route.request();
    let path = new URL(request.url()).pathname;
    if (path === "/") path = "/index.html";
    const file = normalize(join(dir, path));
    served.requests += 1;
    let body;
    try {
      body = await readFile(file);
    } catch {
      return route.fulfill({ status: 404, body: "no such file" });
    }
    const type = TYPES[path.slice(path.lastIndexOf("."))] ?? "application/octet-stream";
    const range = /^bytes=(\d+)-(\d+)$/.exec(request.headers()["range"] ?? "");
    if (range) {
      served.ranged += 1;
      const [a, b] = [Number(range[1]), Math.min(Number(range[2]), body.length - 1)];
      return route.fulfill({
        status: 206,
        headers: { "content-type": type, "content-range": `bytes ${a}-${b}/${body.length}` },
        body: body.subarray(a, b + 1),
      });
    }
    return route.fulfill({ status: 200, headers: { "content-type": type }, body });
  });
}

async function canvasPoint(x, y) {
  const box = await page.locator("#view").boundingBox();
  const size = await page.evaluate(() => [document.getElementById("view").width, document.getElementById("view").height]);
  return [box.x + (x + 0.5) * box.width / size[0], box.y + (y + 0.5) * box.height / size[1]];
}

async function handle(req) {
  switch (req.op) {
    case "open":
      await page.goto(req.url);
      return page.url();
    case "eval":
      return await page.evaluate(`(async () => (${req.js}))()`);
    case "wait": {
      // Until the page has defined what the expression reads, it is false.
      const js = `(() => { try { return (${req.js}); } catch (e) { if (e instanceof ReferenceError) return false; throw e; } })()`;
      const handle = await page.waitForFunction(js, null, { timeout: req.timeout ?? 60000, polling: 50 });
      return await handle.jsonValue();
    }
    case "mouse": {
      const [px, py] = await canvasPoint(req.x ?? 0, req.y ?? 0);
      await page.mouse.move(px, py);
      if (req.action === "down") await page.mouse.down({ button: req.button ?? "left" });
      if (req.action === "up") await page.mouse.up({ button: req.button ?? "left" });
      return [px, py];
    }
    case "hold":
      await page.waitForTimeout(req.ms);
      return req.ms;
    case "type":
      await page.fill(req.selector, req.text);
      if (req.enter) await page.press(req.selector, "Enter");
      return req.text;
    case "key":
      await page.locator("#view").focus();
      await page.keyboard.press(req.key);
      return req.key;
    case "screenshot":
      await page.screenshot({ path: req.path });
      return req.path;
    case "backend":
      // What the page's GPU access would be: WebGL2's renderer (SwiftShader where software).
      return await page.evaluate(() => {
        const gl = document.createElement("canvas").getContext("webgl2");
        if (!gl) return "no WebGL2";
        const info = gl.getExtension("WEBGL_debug_renderer_info");
        return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
      });
    case "download": {
      // Clicks `selector` and saves what the page offers for download at `path`.
      const [download] = await Promise.all([page.waitForEvent("download"), page.click(req.selector)]);
      await download.saveAs(req.path);
      return download.suggestedFilename();
    }
    case "site":
      await serveSite(req.dir, req.origin);
      return served;
    case "served":
      return served;
    case "console":
      return console_lines;
    case "close":
      await browser.close();
      await server.close();
      return "closed";
    default:
      throw new Error(`unknown op ${req.op}`);
  }
}

const lines = createInterface({ input: process.stdin });
for await (const line of lines) {
  if (!line.trim()) continue;
  let answer;
  try {
    answer = { ok: await handle(JSON.parse(line)) };
  } catch (e) {
    answer = { error: String(e.message ?? e) };
  }
  process.stdout.write(JSON.stringify(answer) + "\n");
  if (JSON.parse(line).op === "close") break;
}
await server.close().catch(() => {});
process.exit(0);
