// The page of an exported glassbake site: fetches the site's files, opens the module's Viewer on
// the canvas and draws a frame whenever the view or a variable changes. `window.glassbake`
// exposes the same to scripts (the headless browser test draws and reads frames through it).
import init, { Viewer, has_webgpu } from './glassbake_web.js';

// A panic in the module logs its stack: deep enough to name the code that panicked.
Error.stackTraceLimit = 64;

const canvas = document.getElementById('frame');
const stats = document.getElementById('stats');

function fail(text) {
  const message = document.getElementById('message');
  message.textContent = text;
  message.hidden = false;
  stats.textContent = '';
  window.glassbake = { error: text };
}

async function fetched(name, as) {
  const response = await fetch(name);
  if (!response.ok) throw new Error(`${name}: ${response.status} ${response.statusText}`);
  return as === 'text' ? response.text() : new Uint8Array(await response.arrayBuffer());
}

async function open() {
  await init();
  if (!has_webgpu()) {
    fail('This page draws the scene with WebGPU, which this browser does not offer. Open it in a current Chrome, Edge or Safari, or in Firefox with WebGPU enabled.');
    return;
  }
  const siteText = await fetched('site.json', 'text');
  const site = JSON.parse(siteText);
  const sceneNames = site.scene.kind === 'files' ? site.scene.files : [];
  const [config, weights, ...sceneFiles] = await Promise.all([
    fetched(site.model_config, 'text'),
    fetched(site.model_weights),
    ...sceneNames.map((name) => fetched(name)),
  ]);
  const viewer = await Viewer.open(canvas, siteText, config, weights, sceneNames, sceneFiles);
  document.title = `${site.title} - glassbake`;
  document.getElementById('title').textContent = site.title;

  const orbit = site.orbit;
  const mid = (i) => 0.5 * (i.min + i.max);
  const clamp = (v, i) => Math.min(i.max, Math.max(i.min, v));
  const view = { azimuth: mid(orbit.azimuth), elevation: mid(orbit.elevation), distance: mid(orbit.distance) };
  const values = site.variables.map((v) => v.default);

  const sliders = document.getElementById('variables');
  site.variables.forEach((variable, i) => {
    const label = document.createElement('label');
    const input = document.createElement('input');
    Object.assign(input, { type: 'range', min: variable.min, max: variable.max, step: (variable.max - variable.min) / 200 || 1, value: variable.default });
    label.textContent = `${variable.name} (${variable.kind})`;
    input.setAttribute('aria-label', variable.name);
    input.addEventListener('input', () => { values[i] = Number(input.value); request(); });
    sliders.append(label, input);
  });

  let drawing = null;
  let wanted = true;
  let frames = 0;
  // The canvas as shown: RGBA bytes, rows from the top. A WebGPU canvas is read while its
  // frame is still the current texture, in the task that drew it.
  function canvasPixels() {
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const context = copy.getContext('2d');
    context.drawImage(canvas, 0, 0);
    return Array.from(context.getImageData(0, 0, copy.width, copy.height).data);
  }
  let lastCanvas = null;
  async function draw(capture = false) {
    const start = performance.now();
    viewer.render(view.azimuth, view.elevation, view.distance, Float32Array.from(values));
    lastCanvas = capture ? canvasPixels() : null;
    await viewer.finished();
    const ms = performance.now() - start;
    frames += 1;
    stats.textContent = `${site.resolution} x ${site.resolution} px, frame ${ms.toFixed(1)} ms (${(1000 / ms).toFixed(1)} FPS) on ${viewer.adapter() || 'WebGPU'}`;
    return ms;
  }
  function request() {
    wanted = true;
    if (!drawing) drawing = loop();
  }
  async function loop() {
    while (wanted) {
      wanted = false;
      await new Promise((resolve) => requestAnimationFrame(resolve));
      try { await draw(); } catch (e) { fail(String(e)); break; }
    }
    drawing = null;
  }

  let dragging = null;
  canvas.addEventListener('pointerdown', (e) => { dragging = { x: e.clientX, y: e.clientY }; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener('pointerup', () => { dragging = null; });
  canvas.addEventListener('pointermove', (e) => {
    if (!dragging) return;
    const degreesPerPixel = 180 / canvas.clientWidth;
    view.azimuth = clamp(view.azimuth - (e.clientX - dragging.x) * degreesPerPixel, orbit.azimuth);
    view.elevation = clamp(view.elevation + (e.clientY - dragging.y) * degreesPerPixel, orbit.elevation);
    dragging = { x: e.clientX, y: e.clientY };
    request();
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    view.distance = clamp(view.distance * Math.exp(e.deltaY * 0.001), orbit.distance);
    request();
  }, { passive: false });

  const firstMs = await draw();
  window.glassbake = {
    site,
    firstFrameMs: performance.now(),
    firstFrameDrawMs: firstMs,
    frames: () => frames,
    // Draws one frame of the given view and values and resolves with its time in ms; with
    // `capture`, keeps the canvas's pixels for `readCanvas`.
    draw: async (next, capture = false) => {
      Object.assign(view, next.view || {});
      (next.values || []).forEach((v, i) => { values[i] = v; });
      return draw(capture);
    },
    // The canvas of the last frame drawn with `capture`: RGBA bytes, rows from the top.
    readCanvas: () => lastCanvas,
    // The last frame read back from the GPU (the same pixels, without the browser's canvas).
    readFrame: async () => Array.from(await viewer.pixels()),
  };
}

open().catch((e) => fail(`The scene could not be opened: ${e && e.message ? e.message : e}`));
