// The web display's benchmark in Debian's chromium, headless: opens URL (a
// page served by `holodeck serve --web`, or an exported site), then for each
// view line on standard input moves there and times the view change until
// every stored ray of the view is in (samples, bytes, milliseconds), then
// times FRAMES frames. Prints one JSON object. Used by docs/results/web.sh.
//
//   node bench.mjs URL FRAMES < views.vf
import { readFileSync } from "node:fs";
import { chromium } from "playwright-core";

const [url, frames] = [process.argv[2], Number(process.argv[3] || 20)];
const views = readFileSync(0, "utf8").split("\n").map((l) => l.trim()).filter((l) => l && !l.startsWith("#"));
const server = await chromium.launchServer({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: ["--headless=new", "--no-sandbox", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-quic"],
});
try {
  const browser = await chromium.connect(server.wsEndpoint());
  const page = await browser.newPage();
  const start = Date.now();
  await page.goto(url);
  await page.waitForFunction("window.holodeck && holodeck.open() && holodeck.transfers() === 0 && holodeck.samples() > 0",
    null, { timeout: 300000, polling: 5 });
  const first = {
    ms: Date.now() - start,
    samples: await page.evaluate("holodeck.samples()"),
    bytes: await page.evaluate("holodeck.bytes()"),
    timing: await page.evaluate("holodeck.timing()"),
    frames: await page.evaluate("holodeck.frames()"),
  };
  const changes = [];
  for (const line of views) {
    changes.push(await page.evaluate(async (line) => {
      const [s0, b0, t0] = [holodeck.samples(), holodeck.bytes(), performance.now()];
      holodeck.line(line);
      await new Promise((done) => {
        const check = () => (holodeck.transfers() === 0 ? done() : setTimeout(check, 1));
        check();
      });
      return { ms: performance.now() - t0, samples: holodeck.samples() - s0, bytes: holodeck.bytes() - b0 };
    }, line));
  }
  const frame = await page.evaluate((n) => holodeck.benchFrames(n), frames);
  const where = await page.evaluate("holodeck.where()");
  process.stdout.write(JSON.stringify({ first, changes, frame, where }) + "\n");
} finally {
  await server.close();
}
