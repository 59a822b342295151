// Runs the vectorizer off the page's thread, so the page stays responsive while it draws.
// Messages in: {id, bytes, name, settings}; out: {id, kind: "progress" | "done" | "error", ...}.
import init, { Vectorizer } from "./pkg/web.js";

const ready = init().then(() => new Vectorizer());

onmessage = async ({ data: { id, bytes, name, settings } }) => {
  let vectorizer;
  try {
    vectorizer = await ready;
  } catch (err) {
    postMessage({ id, kind: "error", fatal: true, message: `could not start the vectorizer: ${err.message ?? err}` });
    return;
  }
  const started = performance.now();
  try {
    const progress = (seconds, psnr) => postMessage({ id, kind: "progress", seconds, psnr });
    const drawn = vectorizer.vectorize(new Uint8Array(bytes), name, JSON.stringify(settings), progress);
    const seconds = (performance.now() - started) / 1000;
    postMessage({ id, kind: "done", svg: drawn.svg, report: JSON.parse(drawn.report), seconds });
    drawn.free();
  } catch (err) {
    // A Rust error arrives as an Error with its message; a trap (a bug) leaves the module
    // unusable, so the page starts a fresh worker after it.
    const fatal = err instanceof WebAssembly.RuntimeError;
    const message = fatal ? `${name}: internal error (${err.message}); please report it` : err.message ?? String(err);
    postMessage({ id, kind: "error", fatal, message });
  }
};
