// Screenshots a Ferrobot recording, or a live view, opened in a web build of Lichtblick, in a
// headless Chromium.
//
// One local HTTP server (127.0.0.1 only) serves the Lichtblick build with our layout put in its
// index.html (the LICHTBLICK_SUITE_DEFAULT_LAYOUT placeholder that Lichtblick's own Docker image
// fills), and the recording with range requests (Lichtblick's "remote file" source reads MCAP by
// ranges). The page opens `?ds=remote-file&ds.url=...&time=...`; every request that is not to
// this server is refused. The screenshot is taken once the panels have drawn and the page has
// stopped changing, not after a fixed sleep alone; it fails if Lichtblick's Problems list is not
// empty.
//
// A live view (`--live ws://127.0.0.1:8765`, a Ferrobot view server on this machine) opens as
// `?ds=foxglove-websocket&ds.url=...`: Lichtblick's Foxglove WebSocket connection.
//
// node screenshot.mjs --web DIR (--recording FILE.mcap | --live WS-URL) --layout layout.json
//   --out shot.png [--width 1600] [--height 1000] [--at 0.75] [--chromium /usr/bin/chromium]
//   [--timeout 120] [--theme light|dark] [--port N (0: any free one; the app bar shows the
//   recording's URL)] [--wait-for FILE (a live view: take it once FILE exists)]

import fs from "node:fs";
import http from "node:http";
import os from "node:os";
import path from "node:path";

import { chromium } from "playwright-core";

function parseArgs(argv) {
  const args = {
    width: 1600,
    height: 1000,
    at: 0.75,
    chromium: "/usr/bin/chromium",
    timeout: 120,
    theme: "light",
    port: 0,
  };
  for (let i = 0; i < argv.length; i += 2) {
    const key = argv[i];
    const value = argv[i + 1];
    if (!key.startsWith("--") || value === undefined) {
      throw new Error(`bad argument ${key}`);
    }
    args[key.slice(2)] = value;
  }
  for (const required of ["web", "layout", "out"]) {
    if (!args[required]) {
      throw new Error(`--${required} is required`);
    }
  }
  if (!args.recording === !args.live) {
    throw new Error("one of --recording and --live is required");
  }
  if (args.live && !/^ws:\/\/(127\.0\.0\.1|localhost):\d+\/?$/.test(args.live)) {
    throw new Error(`--live ${args.live}: a ws:// URL on this machine`);
  }
  for (const number of ["width", "height", "at", "timeout", "port"]) {
    args[number] = Number(args[number]);
  }
  return args;
}

// The first and last message times (ns) from the MCAP summary's Statistics record.
function mcapTimeRange(file) {
  const fd = fs.openSync(file, "r");
  try {
    const size = fs.fstatSync(fd).size;
    const footer = Buffer.alloc(37);
    fs.readSync(fd, footer, 0, 37, size - 37);
    if (footer[0] !== 0x02 || footer.subarray(29, 37).toString("latin1") !== "\x89MCAP0\r\n") {
      throw new Error(`${file}: no MCAP footer`);
    }
    const summaryStart = Number(footer.readBigUInt64LE(9));
    const summaryOffsetStart = Number(footer.readBigUInt64LE(17));
    if (summaryStart === 0) {
      throw new Error(`${file}: no summary section`);
    }
    const end = summaryOffsetStart !== 0 ? summaryOffsetStart : size - 37;
    const summary = Buffer.alloc(end - summaryStart);
    fs.readSync(fd, summary, 0, summary.length, summaryStart);
    for (let at = 0; at + 9 <= summary.length; ) {
      const op = summary[at];
      const len = Number(summary.readBigUInt64LE(at + 1));
      if (op === 0x0b) {
        // message_count u64, schema_count u16, channel_count u32, attachment_count u32,
        // metadata_count u32, chunk_count u32, then message_start_time, message_end_time.
        const body = at + 9 + 8 + 2 + 4 + 4 + 4 + 4;
        return [summary.readBigUInt64LE(body), summary.readBigUInt64LE(body + 8)];
      }
      at += 9 + len;
    }
    throw new Error(`${file}: no Statistics record in the summary`);
  } finally {
    fs.closeSync(fd);
  }
}

function rfc3339(ns) {
  const secs = ns / 1_000_000_000n;
  const nanos = ns % 1_000_000_000n;
  const date = new Date(Number(secs) * 1000).toISOString().replace(/\.\d+Z$/, "");
  return `${date}.${nanos.toString().padStart(9, "0")}Z`;
}

const MIME = {
  ".html": "text/html; charset=utf-8",
  ".js": "text/javascript; charset=utf-8",
  ".mjs": "text/javascript; charset=utf-8",
  ".css": "text/css; charset=utf-8",
  ".json": "application/json",
  ".wasm": "application/wasm",
  ".png": "image/png",
  ".svg": "image/svg+xml",
  ".ico": "image/x-icon",
  ".woff2": "font/woff2",
  ".woff": "font/woff",
  ".ttf": "font/ttf",
  ".webmanifest": "application/manifest+json",
};

function serve({ web, recording, layout, port }) {
  const indexPath = path.join(web, "index.html");
  const placeholder = "/*LICHTBLICK_SUITE_DEFAULT_LAYOUT_PLACEHOLDER*/";
  const index = fs.readFileSync(indexPath, "utf8");
  if (!index.includes(placeholder)) {
    throw new Error(`${indexPath} has no ${placeholder}: not a Lichtblick web build?`);
  }
  const indexWithLayout = index.replace(placeholder, JSON.stringify(layout));
  const recordingSize = recording ? fs.statSync(recording).size : 0;

  const server = http.createServer((req, res) => {
    const url = new URL(req.url, "http://127.0.0.1");
    const headers = {
      "cross-origin-opener-policy": "same-origin",
      "cross-origin-embedder-policy": "credentialless",
      "cache-control": "no-store",
    };
    if (recording && url.pathname === "/recording.mcap") {
      headers["accept-ranges"] = "bytes";
      headers["content-type"] = "application/octet-stream";
      const range = /^bytes=(\d*)-(\d*)$/.exec(req.headers.range ?? "");
      let start = 0;
      let end = recordingSize - 1;
      let status = 200;
      if (range) {
        if (range[1] === "") {
          start = Math.max(0, recordingSize - Number(range[2]));
        } else {
          start = Number(range[1]);
          end = range[2] === "" ? end : Math.min(end, Number(range[2]));
        }
        if (start > end || start >= recordingSize) {
          res.writeHead(416, { ...headers, "content-range": `bytes */${recordingSize}` });
          res.end();
          return;
        }
        status = 206;
        headers["content-range"] = `bytes ${start}-${end}/${recordingSize}`;
      }
      headers["content-length"] = String(end - start + 1);
      res.writeHead(status, headers);
      if (req.method === "HEAD") {
        res.end();
        return;
      }
      fs.createReadStream(recording, { start, end }).pipe(res);
      return;
    }
    let rel = decodeURIComponent(url.pathname);
    if (rel === "/" || rel === "/index.html") {
      res.writeHead(200, { ...headers, "content-type": MIME[".html"] });
      res.end(indexWithLayout);
      return;
    }
    rel = path.normalize(rel).replace(/^(\.\.[/\\])+/, "");
    const file = path.join(web, rel);
    if (!file.startsWith(path.resolve(web)) || !fs.existsSync(file) || fs.statSync(file).isDirectory()) {
      res.writeHead(404, headers);
      res.end("not found");
      return;
    }
    headers["content-type"] = MIME[path.extname(file)] ?? "application/octet-stream";
    res.writeHead(200, headers);
    fs.createReadStream(file).pipe(res);
  });
  return new Promise((resolve, reject) => {
    server.once("error", reject);
    server.listen(port, "127.0.0.1", () => resolve(server));
  });
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const web = path.resolve(args.web);
  const recording = args.recording ? path.resolve(args.recording) : undefined;
  const layout = JSON.parse(fs.readFileSync(args.layout, "utf8"));
  let atNs;
  if (recording) {
    const [startNs, endNs] = mcapTimeRange(recording);
    atNs = startNs + BigInt(Math.round(Number(endNs - startNs) * args.at));
  }

  const server = await serve({ web, recording, layout, port: args.port });
  const origin = `http://127.0.0.1:${server.address().port}`;
  const query = recording
    ? new URLSearchParams({
        ds: "remote-file",
        "ds.url": `${origin}/recording.mcap`,
        time: rfc3339(atNs),
      })
    : new URLSearchParams({ ds: "foxglove-websocket", "ds.url": args.live });
  // What the app bar names once the source is open.
  const sourceName = recording ? "recording.mcap" : new URL(args.live).host;
  const pageUrl = `${origin}/?${query}`;
  console.log(`serving ${web} and ${recording ?? args.live} at ${origin}; opening ${pageUrl}`);

  const profile = fs.mkdtempSync(path.join(os.tmpdir(), "ferrobot-viewer-"));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: args.chromium,
    headless: true,
    viewport: { width: args.width, height: args.height },
    deviceScaleFactor: 1,
    colorScheme: args.theme,
    args: [
      "--no-sandbox",
      "--disable-gpu",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--disable-quic",
      "--no-first-run",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
    ],
  });
  const problems = [];
  try {
    // Nothing leaves this machine: only our own server answers.
    await context.route("**/*", (route) => {
      const url = route.request().url();
      const live = args.live && url.startsWith(args.live.replace(/\/$/, ""));
      if (url.startsWith(`${origin}/`) || live || url.startsWith("data:") || url.startsWith("blob:")) {
        return route.continue();
      }
      problems.push(`refused ${url}`);
      return route.abort();
    });
    const page = context.pages()[0] ?? (await context.newPage());
    page.on("console", (msg) => {
      if (msg.type() === "error" || process.env.VIEWER_DEBUG) {
        problems.push(`console: ${msg.text()}`);
      }
    });
    page.on("pageerror", (err) => problems.push(`page error: ${err.stack ?? err.message}`));
    page.on("requestfailed", (req) => {
      const error = req.failure()?.errorText ?? "";
      // Lichtblick cancels the range reads it no longer needs: not a problem.
      if (!(req.url().endsWith("/recording.mcap") && error === "net::ERR_ABORTED")) {
        problems.push(`request failed: ${req.url()} ${error}`);
      }
    });
    page.on("response", (res) => {
      if (res.status() >= 400) {
        problems.push(`HTTP ${res.status()}: ${res.url()}`);
      }
    });

    const deadline = Date.now() + args.timeout * 1000;
    const left = () => Math.max(1000, deadline - Date.now());
    await page.goto(pageUrl, { waitUntil: "load", timeout: left() });

    // The three panels mounted (each draws into a canvas) ...
    await page.waitForFunction(() => document.querySelectorAll("canvas").length >= 3, null, {
      timeout: left(),
      polling: 250,
    });
    // ... the recording (or the live view) opened: its name in the app bar, with no loading
    // spinner left.
    await page.waitForFunction(
      (name) =>
        document.body.innerText.includes(name) &&
        document.querySelectorAll('[role="progressbar"]').length === 0,
      sourceName,
      { timeout: left(), polling: 250 },
    );
    // Lichtblick's Problems list (topics it could not read, schemas it could not parse, ...)
    // is empty.
    await page.getByRole("tab", { name: "Problems" }).first().click();
    const listed = await page
      .getByText("No problems found")
      .first()
      .waitFor({ timeout: 10_000 })
      .then(() => undefined)
      .catch(() => page.locator("body").innerText());
    if (listed !== undefined) {
      throw new Error(`Lichtblick lists problems with ${sourceName}:\n${listed}`);
    }
    console.log("Lichtblick's Problems list: no problems found");
    // The left sidebar closed: more room for the panels.
    const hideLeft = page.getByRole("button", { name: "Hide left sidebar" });
    if ((await hideLeft.count()) > 0) {
      await hideLeft.first().click();
    }
    // The pointer off the buttons, so that no tooltip shows.
    await page.mouse.move(Math.round(args.width / 4), 18);
    // A live view: until its program says the robot stands still (--wait-for FILE exists).
    while (args["wait-for"] && !fs.existsSync(args["wait-for"])) {
      if (Date.now() > deadline) {
        throw new Error(`${args["wait-for"]} did not appear before the timeout`);
      }
      await page.waitForTimeout(250);
    }
    // ... then wait until two screenshots a second apart are the same (the 3D panel, the
    // image and the plot have finished drawing), at least 2 s after the above.
    await page.waitForTimeout(2000);
    let previous = await page.screenshot();
    let stable = false;
    while (Date.now() < deadline) {
      await page.waitForTimeout(1000);
      const current = await page.screenshot();
      if (current.equals(previous)) {
        stable = true;
        break;
      }
      previous = current;
    }
    if (!stable) {
      throw new Error("the page kept changing until the timeout");
    }
    fs.mkdirSync(path.dirname(path.resolve(args.out)), { recursive: true });
    fs.writeFileSync(args.out, previous);
    const when = recording ? ` at ${rfc3339(atNs)}` : ` of ${args.live}`;
    console.log(`wrote ${args.out} (${args.width}x${args.height})${when}`);
    for (const problem of problems) {
      console.log(`note: ${problem}`);
    }
  } catch (err) {
    for (const problem of problems) {
      console.error(problem);
    }
    const pages = context.pages();
    if (pages.length > 0) {
      const failed = `${args.out}.failed.png`;
      await pages[0].screenshot({ path: failed }).catch(() => {});
      console.error(`the page as it was: ${failed}`);
    }
    throw err;
  } finally {
    await context.close();
    server.close();
    fs.rmSync(profile, { recursive: true, force: true });
  }
}

main().catch((err) => {
  console.error(err.stack ?? String(err));
  process.exit(1);
});
