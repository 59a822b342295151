// The page: controls, the worker that draws, the linked zoom, the download.
const $ = (id) => document.getElementById(id);
const LARGEST_FILE = 64 << 20;

let worker = null;
let image = null; // {name, bytes}
let running = null; // id of the drawing under way
let queued = false; // settings or the image changed while drawing
let nextId = 0;
let svgUrl = null;

function startWorker() {
  worker = new Worker(new URL("worker.js", import.meta.url), { type: "module" });
  worker.onmessage = ({ data }) => receive(data);
  worker.onerror = (event) => {
    show("error", `the vectorizer failed to load: ${event.message ?? "see the console"}`);
    running = null;
  };
}

function settings() {
  const finetune = Number($("finetune").value);
  return {
    paths: $("paths-auto").checked ? "auto" : $("paths").value,
    tolerance: $("curves").checked ? Number($("tolerance").value) : undefined,
    fills: $("fills").value || undefined,
    finetune_secs: finetune > 0 ? finetune : undefined,
  };
}

function show(state, text) {
  $("message").dataset.state = state;
  $("message").textContent = text;
  $("progress").hidden = state !== "working";
}

function draw() {
  if (!image) return;
  if (running !== null) {
    queued = true;
    return;
  }
  queued = false;
  running = nextId++;
  const job = settings();
  show("working", `Drawing ${image.name}…`);
  const progress = $("progress");
  progress.removeAttribute("value");
  progress.max = job.finetune_secs ?? 1;
  worker.postMessage({ id: running, bytes: image.bytes, name: image.name, settings: job });
}

function receive(data) {
  if (data.id !== running) return;
  if (data.kind === "progress") {
    $("progress").value = data.seconds;
    $("message").textContent = `Fine-tuning ${image.name}: ${data.psnr.toFixed(2)} dB`;
    return;
  }
  running = null;
  if (data.kind === "done") {
    const { report, svg, seconds } = data;
    if (svgUrl) URL.revokeObjectURL(svgUrl);
    svgUrl = URL.createObjectURL(new Blob([svg], { type: "image/svg+xml" }));
    $("drawing").src = svgUrl;
    const download = $("download");
    download.href = svgUrl;
    download.download = image.name.replace(/\.[^.]*$/, "") + ".svg";
    download.hidden = false;
    $("stats").textContent =
      `${report.paths} paths · ${(report.svg_bytes / 1024).toFixed(1)} KB · ` +
      `${report.psnr.toFixed(2)} dB PSNR · ${seconds.toFixed(2)} s`;
    show("done", `Drew ${image.name}.`);
  } else {
    show("error", data.message);
    $("stats").textContent = "";
    $("download").hidden = true;
    if (data.fatal) {
      worker.terminate();
      startWorker();
    }
  }
  if (queued) draw();
}

async function pick(file) {
  if (!file) return;
  if (file.size > LARGEST_FILE) {
    show("error", `${file.name}: too large (${(file.size / 2 ** 20).toFixed(0)} MB); the page takes files up to 64 MB`);
    return;
  }
  image = { name: file.name, bytes: await file.arrayBuffer() };
  URL.revokeObjectURL($("original").src);
  $("original").src = URL.createObjectURL(file);
  $("drawing").removeAttribute("src");
  $("download").hidden = true;
  $("stats").textContent = "";
  draw();
}

function wireControls() {
  $("file").addEventListener("change", (event) => pick(event.target.files[0]));
  const drop = $("drop");
  drop.addEventListener("dragover", (event) => {
    event.preventDefault();
    drop.classList.add("over");
  });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (event) => {
    event.preventDefault();
    drop.classList.remove("over");
    pick(event.dataTransfer.files[0]);
  });
  const label = () => {
    $("paths-value").textContent = $("paths-auto").checked ? "auto" : $("paths").value;
    $("paths").disabled = $("paths-auto").checked;
    $("tolerance").disabled = !$("curves").checked;
    $("tolerance-value").textContent = $("curves").checked ? `${$("tolerance").value} px` : "off";
    const finetune = Number($("finetune").value);
    $("finetune-value").textContent = finetune > 0 ? `${finetune} s` : "off";
  };
  for (const id of ["paths", "tolerance", "finetune"]) $(id).addEventListener("input", label);
  for (const id of ["paths", "paths-auto", "curves", "tolerance", "fills", "finetune"]) {
    $(id).addEventListener("change", () => {
      label();
      draw();
    });
  }
  label();
}

// Both pictures zoom and pan together: the wheel zooms around the pointer, dragging pans,
// a double-click resets.
function wireZoom() {
  let view = { scale: 1, x: 0, y: 0 };
  const apply = () => {
    for (const id of ["original", "drawing"]) {
      $(id).style.transform = `translate(${view.x}px, ${view.y}px) scale(${view.scale})`;
    }
  };
  for (const box of document.querySelectorAll(".view")) {
    box.addEventListener("wheel", (event) => {
      event.preventDefault();
      const rect = box.getBoundingClientRect();
      const [px, py] = [event.clientX - rect.left, event.clientY - rect.top];
      const scale = Math.min(64, Math.max(1, view.scale * Math.exp(-event.deltaY / 500)));
      const k = scale / view.scale;
      view = { scale, x: px - (px - view.x) * k, y: py - (py - view.y) * k };
      apply();
    }, { passive: false });
    let dragging = null;
    box.addEventListener("pointerdown", (event) => {
      dragging = { x: event.clientX - view.x, y: event.clientY - view.y };
      box.setPointerCapture(event.pointerId);
    });
    box.addEventListener("pointermove", (event) => {
      if (!dragging) return;
      view = { ...view, x: event.clientX - dragging.x, y: event.clientY - dragging.y };
      apply();
    });
    box.addEventListener("pointerup", () => (dragging = null));
    box.addEventListener("dblclick", () => {
      view = { scale: 1, x: 0, y: 0 };
      apply();
    });
  }
}

startWorker();
wireControls();
wireZoom();
