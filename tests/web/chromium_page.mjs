// chromium_page.mjs — runs one test page in headless Chromium (SwiftShader
// WebGPU) and collects what it POSTs back, for the harnesses in tests/web
// (webgpu_harness.mjs, lod_harness.mjs). No npm deps: a node:http server on
// 127.0.0.1 serves the page at /, the repository's web/ folder under /web/
// and the given files; the page POSTs /result/NAME bodies and ends with
// /result/done or /result/error. /result/log lines go to stderr with
// HARNESS_VERBOSE set.
import { createServer } from "node:http";
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync, existsSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, dirname, resolve, extname } from "node:path";
import { fileURLToPath } from "node:url";

const webDir = resolve(dirname(fileURLToPath(import.meta.url)), "../../web");
const TYPES = { ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json", ".wasm": "application/wasm" };

/** The import map a page needs for the reader's two npm modules. */
export const IMPORT_MAP = `<script type="importmap">{"imports": {"fzstd": "/web/node_modules/fzstd/esm/index.mjs",
 "xxhash-wasm": "/web/node_modules/xxhash-wasm/esm/xxhash-wasm.js"}}</script>`;

/**
 * Serves `page` and `files` ({"/path": local file path | {json: value}}),
 * runs Chromium on it and resolves to the POSTed bodies by name (Buffers).
 * Rejects with the page's error, Chromium's early exit (its log's tail) or
 * a timeout.
 * @param {{page: string, files: Record<string, string | {json: unknown}>, width?: number,
 *          height?: number, timeoutS?: number}} opts
 * @returns {Promise<Record<string, Buffer>>}
 */
export async function runPage({ page, files, width = 640, height = 360, timeoutS = 600 }) {
  let chromium = null;
  const results = {};
  const finished = new Promise((resolveDone) => {
    const server = createServer((req, res) => {
      const url = new URL(req.url, "http://x");
      if (req.method === "POST") {
        const parts = [];
        req.on("data", (c) => parts.push(c));
        req.on("end", () => {
          const body = Buffer.concat(parts);
          const what = url.pathname.replace("/result/", "");
          results[what] = body;
          if (what === "log" && process.env.HARNESS_VERBOSE) console.error("page: " + body.toString());
          res.end("ok");
          if (what === "done" || what === "error") resolveDone(server);
        });
        return;
      }
      if (url.pathname === "/") { res.setHeader("content-type", "text/html"); res.end(page); return; }
      let file = null, type = "application/octet-stream";
      const given = files[url.pathname];
      if (given && typeof given === "object") {
        res.setHeader("content-type", "application/json");
        res.end(JSON.stringify(given.json));
        return;
      }
      if (given) file = resolve(given);
      else if (url.pathname.startsWith("/web/")) {
        file = resolve(webDir, "." + url.pathname.slice(4));
        if (!file.startsWith(webDir)) file = null;
        type = TYPES[extname(file ?? "")] ?? type;
      }
      if (!file || !existsSync(file)) { res.statusCode = 404; res.end("not found"); return; }
      res.setHeader("content-type", type);
      res.end(readFileSync(file));
    });
    server.listen(0, "127.0.0.1", () => {
      const port = server.address().port;
      const profile = mkdtempSync(join(tmpdir(), "chromium-page-"));
      chromium = spawn("/usr/bin/chromium", ["--headless", "--no-sandbox", "--enable-unsafe-webgpu",
        "--enable-unsafe-swiftshader", `--user-data-dir=${profile}`, `--window-size=${width},${height}`,
        "--enable-logging=stderr", "--v=0", `http://127.0.0.1:${port}/`], { stdio: ["ignore", "ignore", "pipe"] });
      let log = "";
      chromium.stderr.on("data", (c) => { log += c; if (process.env.HARNESS_VERBOSE) process.stderr.write(c); });
      chromium.on("exit", () => {
        // Chromium's helpers may still write into the profile as it goes.
        try { rmSync(profile, { recursive: true, force: true, maxRetries: 5, retryDelay: 100 }); } catch { /* left in tmp */ }
        if (!results.done && !results.error) {
          results.error = Buffer.from("chromium exited early:\n" + log.slice(-3000));
          resolveDone(server);
        }
      });
    });
  });
  let timer = null;
  const timeout = new Promise((_, reject) => {
    timer = setTimeout(() => { chromium?.kill(); reject(new Error(`timeout after ${timeoutS} s`)); }, timeoutS * 1000);
  });
  const server = await Promise.race([finished, timeout]);
  clearTimeout(timer);
  chromium?.kill();
  server.close();
  if (results.error && !results.done) throw new Error("page error: " + results.error.toString());
  return results;
}
