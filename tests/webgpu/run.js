// Runs knotwork's kernels (tessellate.wgsl, curves.wgsl, coons.wgsl) in Chromium's own
// WebGPU — Dawn with its Tint compiler on SwiftShader, headless — on the inputs
// `knotwork conformance --export DIR` wrote, reads the results back and holds them to the
// conformance suite's bars against the f64 expectations written beside them. Prints a table
// and a verdict; exits 1 if a case fails.
//
//   KNOTWORK_WEBGPU_HARNESS=<folder with node_modules/playwright-core> node tests/webgpu/run.js DIR [CASE...]
//
// CASE: run only the cases with these file prefixes (case0, ..., curves0, ..., coons0, ...).
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
async function setUp({ wgsl, entryPoints, curveWgsl, curveEntryPoint, coonsWgsl, coonsEntryPoint, viewWgsl, viewEntryPoints, pointsWgsl, pointsEntryPoint }) {
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error('no WebGPU adapter');
  const device = await adapter.requestDevice();
  const compile = async (code) => {
    const module = device.createShaderModule({ code });
    const messages = (await module.getCompilationInfo()).messages;
    const errors = messages.filter((m) => m.type === 'error');
    if (errors.length) {
      throw new Error(errors.map((m) => `${m.lineNum}:${m.linePos} ${m.message}`).join('\n'));
    }
    return module;
  };
  const module = await compile(wgsl);
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
  const curveLayout = device.createBindGroupLayout({
    entries: [storage(0, true), storage(1, true), storage(2, true), storage(3, false)],
  });
  const curvePipeline = await device.createComputePipelineAsync({
    layout: device.createPipelineLayout({ bindGroupLayouts: [curveLayout] }),
    compute: { module: await compile(curveWgsl), entryPoint: curveEntryPoint },
  });
  const coonsLayout = device.createBindGroupLayout({
    entries: [storage(0, true), storage(1, true), storage(2, true), storage(3, false), storage(4, false)],
  });
  const coonsPipeline = await device.createComputePipelineAsync({
    layout: device.createPipelineLayout({ bindGroupLayouts: [coonsLayout] }),
    compute: { module: await compile(coonsWgsl), entryPoint: coonsEntryPoint },
  });
  // view.wgsl (the view-dependent re-planning): compiled by Tint, with its uniformity
  // analysis, and one pipeline per entry point — not dispatched here.
  const viewModule = await compile(viewWgsl);
  for (const entryPoint of viewEntryPoints) {
    await device.createComputePipelineAsync({ layout: 'auto', compute: { module: viewModule, entryPoint } });
  }
  // points.wgsl (trimmed faces' and shells' vertices): compiled, its pipeline made.
  const pointsLayout = device.createBindGroupLayout({
    entries: [storage(0, true), storage(1, true), storage(2, true), storage(3, false)],
  });
  await device.createComputePipelineAsync({
    layout: device.createPipelineLayout({ bindGroupLayouts: [pointsLayout] }),
    compute: { module: await compile(pointsWgsl), entryPoint: pointsEntryPoint },
  });
  // Helpers the runners share (each runner is sent to the page on its own).
  const decode = (b64) => Uint8Array.from(atob(b64), (ch) => ch.charCodeAt(0));
  const encode = (bytes) => {
    let s = '';
    for (let i = 0; i < bytes.length; i += 0x8000) {
      s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    }
    return btoa(s);
  };
  // A buffer of exactly `bytes` (the kernels count jobs by binding length).
  const upload = (bytes, usage) => {
    const buffer = device.createBuffer({ size: bytes.length, usage, mappedAtCreation: true });
    new Uint8Array(buffer.getMappedRange()).set(bytes);
    buffer.unmap();
    return buffer;
  };
  // One invocation per item, 64 per workgroup, as knotwork's dispatch_flat.
  const flat = (pass, items) => {
    const groups = Math.ceil(items / 64);
    const x = Math.min(groups, 65535);
    pass.dispatchWorkgroups(x, Math.ceil(groups / x), 1);
  };
  window.knotwork = {
    device, layout, pipelines, curveLayout, curvePipeline, coonsLayout, coonsPipeline,
    decode, encode, upload, flat,
  };
  const info = adapter.info || {};
  return `${info.vendor || '?'} ${info.architecture || ''} ${info.description || ''}`.trim();
}

// In the page: uploads one case, dispatches every chunk's passes as GpuBatch does, and
// returns the vertex and index buffers (base64).
async function runCase({ c, files, stride }) {
  const { device, layout, pipelines, decode, encode, upload } = window.knotwork;
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

// In the page: one curve case, chunk by chunk as GpuTessellator's curve work does (bindings
// 0..=2 exactly the chunk's bytes: the kernel counts curves by the length of binding 0); returns
// every chunk's samples (base64).
async function runCurves({ chunks, sampleBytes }) {
  const { device, curveLayout, curvePipeline, decode, encode, upload, flat } = window.knotwork;
  const S = GPUBufferUsage;
  device.pushErrorScope('validation');
  const encoder = device.createCommandEncoder();
  const reads = [];
  const buffers = [];
  for (const chunk of chunks) {
    const inputs = [chunk.jobs, chunk.points, chunk.tables].map((b64) => upload(decode(b64), S.STORAGE));
    const bytes = chunk.samples * sampleBytes;
    const output = device.createBuffer({ size: bytes, usage: S.STORAGE | S.COPY_SRC });
    const read = device.createBuffer({ size: bytes, usage: S.MAP_READ | S.COPY_DST });
    const group = device.createBindGroup({
      layout: curveLayout,
      entries: [...inputs, output].map((buffer, binding) => ({ binding, resource: { buffer } })),
    });
    const pass = encoder.beginComputePass();
    pass.setPipeline(curvePipeline);
    pass.setBindGroup(0, group);
    flat(pass, chunk.samples);
    pass.end();
    encoder.copyBufferToBuffer(output, 0, read, 0, bytes);
    reads.push(read);
    buffers.push(...inputs, output, read);
  }
  device.queue.submit([encoder.finish()]);
  const error = await device.popErrorScope();
  if (error) throw new Error(`validation: ${error.message}`);
  await Promise.all(reads.map((read) => read.mapAsync(GPUMapMode.READ)));
  const out = reads.map((read) => encode(new Uint8Array(read.getMappedRange())));
  for (const buffer of buffers) buffer.destroy();
  return out;
}

// In the page: one Coons case, chunk by chunk as the Coons executor does — the boundary
// curves sampled by curves.wgsl, then coons.wgsl over them (every binding exactly its bytes:
// the kernels count jobs by the length of binding 0) — returning the vertices and indices of
// all chunks (base64).
async function runCoons({ chunks, sampleBytes }) {
  const { device, curveLayout, curvePipeline, coonsLayout, coonsPipeline, decode, encode, upload, flat } = window.knotwork;
  const S = GPUBufferUsage;
  device.pushErrorScope('validation');
  const encoder = device.createCommandEncoder();
  const reads = [];
  const buffers = [];
  for (const chunk of chunks) {
    const curveInputs = [chunk.boundary_jobs, chunk.boundary_points, chunk.boundary_tables].map((b64) => upload(decode(b64), S.STORAGE));
    const samples = device.createBuffer({ size: chunk.boundary_samples * sampleBytes, usage: S.STORAGE });
    const jobs = upload(decode(chunk.jobs), S.STORAGE);
    const blends = upload(decode(chunk.blends), S.STORAGE);
    const vertices = device.createBuffer({ size: chunk.vertices * 32, usage: S.STORAGE | S.COPY_SRC });
    const indices = device.createBuffer({ size: chunk.indices * 4, usage: S.STORAGE | S.COPY_SRC });
    const bind = (layout, list) => device.createBindGroup({
      layout,
      entries: list.map((buffer, binding) => ({ binding, resource: { buffer } })),
    });
    let pass = encoder.beginComputePass();
    pass.setPipeline(curvePipeline);
    pass.setBindGroup(0, bind(curveLayout, [...curveInputs, samples]));
    flat(pass, chunk.boundary_samples);
    pass.end();
    pass = encoder.beginComputePass();
    pass.setPipeline(coonsPipeline);
    pass.setBindGroup(0, bind(coonsLayout, [jobs, samples, blends, vertices, indices]));
    flat(pass, chunk.vertices);
    pass.end();
    const readVertices = device.createBuffer({ size: chunk.vertices * 32, usage: S.MAP_READ | S.COPY_DST });
    const readIndices = device.createBuffer({ size: chunk.indices * 4, usage: S.MAP_READ | S.COPY_DST });
    encoder.copyBufferToBuffer(vertices, 0, readVertices, 0, chunk.vertices * 32);
    encoder.copyBufferToBuffer(indices, 0, readIndices, 0, chunk.indices * 4);
    reads.push([readVertices, readIndices]);
    buffers.push(...curveInputs, samples, jobs, blends, vertices, indices, readVertices, readIndices);
  }
  device.queue.submit([encoder.finish()]);
  const error = await device.popErrorScope();
  if (error) throw new Error(`validation: ${error.message}`);
  await Promise.all(reads.flat().map((read) => read.mapAsync(GPUMapMode.READ)));
  const out = reads.map(([v, i]) => ({
    vertices: encode(new Uint8Array(v.getMappedRange())),
    indices: encode(new Uint8Array(i.getMappedRange())),
  }));
  for (const buffer of buffers) buffer.destroy();
  return out;
}

// The suite's curve comparison (knotwork::conformance::compare_curves) on the exported
// expectations: per sample 8 f64 — position relative to the curve's origin, C′, the curve's
// control extent, its scale of C′. `gpu` holds 12 f32 per sample: (position, 0), (C′, 0),
// (C″, 0).
function compareCurves(gpu, expected, bars) {
  const f = new Float32Array(gpu.buffer, gpu.byteOffset, gpu.length / 4);
  const e = new Float64Array(expected.buffer.slice(expected.byteOffset, expected.byteOffset + expected.length));
  const samples = e.length / 8;
  const report = { position: 0, tangent: 0, layout: f.length === 12 * samples };
  if (!report.layout) return { ...report, pass: false };
  const length = (v) => Math.hypot(v[0], v[1], v[2]);
  for (let k = 0; k < samples; k++) {
    const g = f.subarray(12 * k, 12 * k + 12);
    const x = e.subarray(8 * k, 8 * k + 8);
    const error = length([g[0] - x[0], g[1] - x[1], g[2] - x[2]]) - bars.f32_rounding * length(x);
    let position = Math.max(error, 0) / x[6];
    let tangent = length([g[4] - x[3], g[5] - x[4], g[6] - x[5]]) / x[7];
    if (![g[0], g[1], g[2], g[4], g[5], g[6]].every(Number.isFinite)) position = tangent = Infinity;
    report.position = Math.max(report.position, position);
    report.tangent = Math.max(report.tangent, tangent);
  }
  report.pass = report.position <= bars.position_rel && report.tangent <= bars.tangent_rel;
  return report;
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
    const adapter = await page.evaluate(setUp, {
      wgsl: read('tessellate.wgsl').toString('utf8'),
      entryPoints: manifest.entry_points,
      curveWgsl: read('curves.wgsl').toString('utf8'),
      curveEntryPoint: manifest.curve_entry_point,
      coonsWgsl: read('coons.wgsl').toString('utf8'),
      coonsEntryPoint: manifest.coons_entry_point,
      viewWgsl: read('view.wgsl').toString('utf8'),
      viewEntryPoints: manifest.view_entry_points,
      pointsWgsl: read('points.wgsl').toString('utf8'),
      pointsEntryPoint: manifest.points_entry_point,
    });
    const bars = manifest.bars;
    console.log(`adapter: ${adapter} (Chromium WebGPU)`);
    console.log(`view.wgsl: compiled, ${manifest.view_entry_points.length} pipelines made`);
    console.log('points.wgsl: compiled, its pipeline made');
    console.log(`bars: position ${bars.position_rel} of the diagonal (+ f32 rounding), normal ${bars.normal} rad (${bars.degenerate_normal} near degenerate points)`);
    let failures = 0;
    const cell = (v) => v.toExponential(3).padStart(11);
    const only = process.argv.slice(3);
    const cases = manifest.cases.filter((c) => only.length === 0 || only.includes(c.prefix));
    for (const c of cases) {
      const files = {};
      for (const name of ['uniforms', 'pieces', 'tiles', 'points', 'tables']) files[name] = read(`${c.prefix}.${name}`).toString('base64');
      const out = await page.evaluate(runCase, { c, files, stride: manifest.uniform_stride });
      const r = compare(c, Buffer.from(out.vertices, 'base64'), Buffer.from(out.indices, 'base64'),
        read(`${c.prefix}.expected`), read(`${c.prefix}.indices`), bars);
      if (!r.pass) failures++;
      console.log(`${c.name.padEnd(48)} ${cell(r.position)} ${cell(r.normal)} ${cell(r.degenerate)} ${cell(r.uv)}  ${r.topology ? '' : 'topology differs '}${r.pass ? 'pass' : 'FAIL'}`);
    }
    const curveCases = manifest.curve_cases.filter((c) => only.length === 0 || only.includes(c.prefix));
    for (const c of curveCases) {
      const chunks = c.chunk_samples.map((samples, k) => {
        const file = (what) => read(`${c.prefix}.${k}.${what}`).toString('base64');
        return { samples, jobs: file('jobs'), points: file('points'), tables: file('tables') };
      });
      const out = await page.evaluate(runCurves, { chunks, sampleBytes: manifest.sample_bytes });
      const gpu = Buffer.concat(out.map((b64) => Buffer.from(b64, 'base64')));
      const r = compareCurves(gpu, read(`${c.prefix}.expected`), bars);
      if (!r.pass) failures++;
      console.log(`${('curves: ' + c.name).padEnd(48)} ${cell(r.position)} ${cell(r.tangent)}  ${r.layout ? '' : 'layout differs '}${r.pass ? 'pass' : 'FAIL'}`);
    }
    const coonsCases = manifest.coons_cases.filter((c) => only.length === 0 || only.includes(c.prefix));
    for (const c of coonsCases) {
      const chunks = c.chunks.map((chunk, k) => {
        const file = (what) => read(`${c.prefix}.${k}.${what}`).toString('base64');
        const names = ['boundary_jobs', 'boundary_points', 'boundary_tables', 'jobs', 'blends'];
        return { ...chunk, ...Object.fromEntries(names.map((name) => [name, file(name)])) };
      });
      const out = await page.evaluate(runCoons, { chunks, sampleBytes: manifest.sample_bytes });
      const vertices = Buffer.concat(out.map((o) => Buffer.from(o.vertices, 'base64')));
      const indices = Buffer.concat(out.map((o) => Buffer.from(o.indices, 'base64')));
      const count = c.chunks.reduce((n, chunk) => n + chunk.vertices, 0);
      const r = compare({ vertices: count }, vertices, indices, read(`${c.prefix}.expected`), read(`${c.prefix}.indices`), bars);
      if (!r.pass) failures++;
      console.log(`${c.name.padEnd(48)} ${cell(r.position)} ${cell(r.normal)} ${cell(r.degenerate)} ${cell(r.uv)}  ${r.topology ? '' : 'topology differs '}${r.pass ? 'pass' : 'FAIL'}`);
    }
    const total = cases.length + curveCases.length + coonsCases.length;
    console.log(`verdict: ${failures === 0 ? `all ${total} cases conform` : `${failures} of ${total} cases fail`}`);
    process.exitCode = failures === 0 ? 0 : 1;
  } finally {
    await browser.close();
  }
}

main().catch((error) => {
  console.error(error);
  process.exit(1);
});
