// Runs knotwork's surface kernels (tessellate.wgsl) in Chromium's own WebGPU — Dawn with its
// Tint compiler on SwiftShader, headless — on the inputs `knotwork conformance --export DIR`
// wrote, reads the vertices back and holds them to the conformance suite's bars against the
// f64 expectations written beside them. Prints a table and a verdict; exits 1 if a case fails.
//
//   KNOTWORK_WEBGPU_HARNESS=<folder with node_modules/playwright-core> node tests/webgpu/run.js DIR [CASE...]
//
// CASE: run only the cases with these file prefixes (case0, case1, ...).
// KNOTWORK_CHROMIUM names the browser (default /usr/bin/chromium, Debian's package).
'use strict';
const fs = require('fs');
const path = require('path');

const folder = process.env.KNOTWORK_WEBGPU_HARNESS;
if (!folder || process.argv.length < 3) {
  console.error('usage: KNOTWORK_WEBGPU_HARNESS=<folder with node_modules/playwright-core> node tests/webgpu/run.js DIR');
  process.exit(2);
}
const { chromium } = require(path.join(folder, 'node_modules', 'playwright-core'));
const dir = process.argv[2];
const manifest = JSON.parse(fs.readFileSync(path.join(dir, 'manifest.json'), 'utf8'));
const read = (name) => fs.readFileSync(path.join(dir, name));

// In the page: a device, the module (compilation errors are fatal) and one pipeline per
// entry point, on one bind group layout — the layout knotwork's GpuContext creates.
async function setUp({ wgsl, entryPoints }) {
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error('no WebGPU adapter');
  const device = await adapter.requestDevice();
  const module = device.createShaderModule({ code: wgsl });
  const messages = (await module.getCompilationInfo()).messages;
  const errors = messages.filter((m) => m.type === 'error');
  if (errors.length) {
    throw new Error(errors.map((m) => `${m.lineNum}:${m.linePos} ${m.message}`).join('\n'));
  }
  const storage = (binding, readOnly) => ({
    binding,
    visibility: GPUShaderStage.COMPUTE,
    buffer: { type: readOnly ? 'read-only-storage' : 'storage' },
  });
  const layout = device.createBindGroupLayout({
    entries: [
      { binding: 0, visibility: GPUShaderStage.COMPUTE, buffer: { type: 'uniform', hasDynamicOffset: true, minBindingSize: 32 } },
      storage(1, true), storage(2, true), storage(3, true), storage(4, true),
      storage(5, false), storage(6, false), storage(7, false),
    ],
  });
  const pipelineLayout = device.createPipelineLayout({ bindGroupLayouts: [layout] });
  const pipelines = [];
  for (const entryPoint of entryPoints) {
    pipelines.push(await device.createComputePipelineAsync({
      layout: pipelineLayout,
      compute: { module, entryPoint },
    }));
  }
  window.knotwork = { device, layout, pipelines };
  const info = adapter.info || {};
  return `${info.vendor || '?'} ${info.architecture || ''} ${info.description || ''}`.trim();
}

// In the page: uploads one case, dispatches every chunk's passes as GpuBatch does, and
// returns the vertex and index buffers (base64).
async function runCase({ c, files, stride }) {
  const { device, layout, pipelines } = window.knotwork;
  const decode = (b64) => Uint8Array.from(atob(b64), (ch) => ch.charCodeAt(0));
  const encode = (bytes) => {
    let s = '';
    for (let i = 0; i < bytes.length; i += 0x8000) {
      s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    }
    return btoa(s);
  };
  const upload = (bytes, usage) => {
    const buffer = device.createBuffer({ size: Math.max(16, Math.ceil(bytes.length / 4) * 4), usage, mappedAtCreation: true });
    new Uint8Array(buffer.getMappedRange()).set(bytes);
    buffer.unmap();
    return buffer;
  };
  const S = GPUBufferUsage;
  device.pushErrorScope('validation');
  const uniform = upload(decode(files.uniforms), S.UNIFORM);
  const inputs = ['pieces', 'tiles', 'points', 'tables'].map((name) => upload(decode(files[name]), S.STORAGE));
  const scratch = device.createBuffer({ size: c.scratch_bytes, usage: S.STORAGE });
  const vertexBytes = c.vertices * 32;
  const indexBytes = Math.max(4, c.indices * 4);
  const vertices = device.createBuffer({ size: vertexBytes, usage: S.STORAGE | S.COPY_SRC });
  const indices = device.createBuffer({ size: indexBytes, usage: S.STORAGE | S.COPY_SRC });
  const encoder = device.createCommandEncoder();
  const pass = encoder.beginComputePass();
  c.chunks.forEach((chunk, chunkIndex) => {
    const bound = [...inputs, vertices, indices];
    const entries = [{ binding: 0, resource: { buffer: uniform, offset: 0, size: 32 } }];
    chunk.bindings.forEach(([offset, size], k) => {
      entries.push({ binding: k < 4 ? k + 1 : k + 2, resource: { buffer: bound[k], offset, size } });
    });
    entries.push({ binding: 5, resource: { buffer: scratch } });
    const group = device.createBindGroup({ layout, entries });
    chunk.passes.forEach(([, tiles], p) => {
      if (tiles === 0) return;
      pass.setPipeline(pipelines[p]);
      pass.setBindGroup(0, group, [(chunkIndex * pipelines.length + p) * stride]);
      const x = Math.min(tiles, 65535);
      pass.dispatchWorkgroups(x, Math.ceil(tiles / x), 1);
    });
  });
  pass.end();
  const readVertices = device.createBuffer({ size: vertexBytes, usage: S.MAP_READ | S.COPY_DST });
  const readIndices = device.createBuffer({ size: indexBytes, usage: S.MAP_READ | S.COPY_DST });
  encoder.copyBufferToBuffer(vertices, 0, readVertices, 0, vertexBytes);
  encoder.copyBufferToBuffer(indices, 0, readIndices, 0, indexBytes);
  device.queue.submit([encoder.finish()]);
  const error = await device.popErrorScope();
  if (error) throw new Error(`validation: ${error.message}`);
  await Promise.all([readVertices.mapAsync(GPUMapMode.READ), readIndices.mapAsync(GPUMapMode.READ)]);
  const out = {
    vertices: encode(new Uint8Array(readVertices.getMappedRange())),
    indices: encode(new Uint8Array(readIndices.getMappedRange()).subarray(0, c.indices * 4)),
  };
  for (const buffer of [uniform, ...inputs, scratch, vertices, indices, readVertices, readIndices]) buffer.destroy();
  return out;
}

// The suite's comparison (knotwork::conformance::compare_with_reference), on the exported
// expectations: per vertex 10 f64 — position relative to the surface's origin, unit normal,
// uv, regular (1/0), the surface's diagonal.
function compare(c, gpu, gpuIndices, expected, expectedIndices, bars) {
  const f = new Float32Array(gpu.buffer, gpu.byteOffset, gpu.length / 4);
  const e = new Float64Array(expected.buffer.slice(expected.byteOffset, expected.byteOffset + expected.length));
  const report = { position: 0, normal: 0, degenerate: 0, uv: 0, topology: Buffer.compare(gpuIndices, expectedIndices) === 0 };
  for (let k = 0; k < c.vertices; k++) {
    const g = f.subarray(8 * k, 8 * k + 8);
    const x = e.subarray(10 * k, 10 * k + 10);
    const d = [g[0] - x[0], g[1] - x[1], g[2] - x[2]];
    const length = (v) => Math.hypot(v[0], v[1], v[2]);
    const error = length(d) - bars.f32_rounding * length(x);
    report.position = Math.max(report.position, Math.max(error, 0) / x[9]);
    const n = [g[3], g[4], g[5]];
    const m = [x[3], x[4], x[5]];
    const cross = [n[1] * m[2] - n[2] * m[1], n[2] * m[0] - n[0] * m[2], n[0] * m[1] - n[1] * m[0]];
    let angle = Math.atan2(length(cross), n[0] * m[0] + n[1] * m[1] + n[2] * m[2]);
    if (!Number.isFinite(angle) || !g.every(Number.isFinite)) angle = Infinity;
    if (x[8] === 1) report.normal = Math.max(report.normal, angle);
    else report.degenerate = Math.max(report.degenerate, angle);
    report.uv = Math.max(report.uv, Math.abs(g[6] - x[6]), Math.abs(g[7] - x[7]));
  }
  report.pass = report.topology && report.position <= bars.position_rel && report.normal <= bars.normal
    && report.degenerate <= bars.degenerate_normal && report.uv <= bars.uv;
  return report;
}

async function main() {
  const browser = await chromium.launch({
    executablePath: process.env.KNOTWORK_CHROMIUM || '/usr/bin/chromium',
    args: ['--enable-unsafe-webgpu', '--no-sandbox', '--enable-features=Vulkan', '--use-webgpu-adapter=swiftshader'],
  });
  try {
    const page = await browser.newPage();
    await page.goto('file://' + path.join(__dirname, 'page.html'));
    const wgsl = read('tessellate.wgsl').toString('utf8');
    const adapter = await page.evaluate(setUp, { wgsl, entryPoints: manifest.entry_points });
    const bars = manifest.bars;
    console.log(`adapter: ${adapter} (Chromium WebGPU)`);
    console.log(`bars: position ${bars.position_rel} of the diagonal (+ f32 rounding), normal ${bars.normal} rad (${bars.degenerate_normal} near degenerate points)`);
    let failures = 0;
    const only = process.argv.slice(3);
    const cases = manifest.cases.filter((c) => only.length === 0 || only.includes(c.prefix));
    for (const c of cases) {
      const files = {};
      for (const name of ['uniforms', 'pieces', 'tiles', 'points', 'tables']) files[name] = read(`${c.prefix}.${name}`).toString('base64');
      const out = await page.evaluate(runCase, { c, files, stride: manifest.uniform_stride });
      const r = compare(c, Buffer.from(out.vertices, 'base64'), Buffer.from(out.indices, 'base64'),
        read(`${c.prefix}.expected`), read(`${c.prefix}.indices`), bars);
      if (!r.pass) failures++;
      const cell = (v) => v.toExponential(3).padStart(11);
      console.log(`${c.name.padEnd(48)} ${cell(r.position)} ${cell(r.normal)} ${cell(r.degenerate)} ${cell(r.uv)}  ${r.topology ? '' : 'topology differs '}${r.pass ? 'pass' : 'FAIL'}`);
    }
    console.log(`verdict: ${failures === 0 ? `all ${cases.length} cases conform` : `${failures} of ${cases.length} cases fail`}`);
    process.exitCode = failures === 0 ? 0 : 1;
  } finally {
    await browser.close();
  }
}

main().catch((error) => {
  console.error(error);
  process.exit(1);
});
