// A stand-in for hwr-ground's HTTP server (docs/ground_viewer.md) for working on the page without the
// C++ build: serves the built page and a fake robot "sim" whose three segments grow chunk by chunk
// (segment 0 is later replaced by a version 1), whose camera walks along x, with two welding
// regions and keyframe images. Commands turn accepted (and change the regions) ~1 s after they are
// posted. Node's http module only; everything is kept in memory (a restart starts over).
//
//   node dev/mock_server.mjs [--port 8090] [--host 127.0.0.1] [--web-root DIR] [--speed 1]
//
// Prints "mock: viewer at http://HOST:PORT/" once listening (port 0: a free one).
import { createReadStream, existsSync, statSync } from 'node:fs';
import { createServer } from 'node:http';
import { dirname, extname, join, normalize, resolve, sep } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const options = { port: 8090, host: '127.0.0.1', webRoot: resolve(here, '../../../../build/web/dist'), speed: 1 };
for (let i = 2; i < process.argv.length; i += 2) {
  const [flag, value] = [process.argv[i], process.argv[i + 1]];
  if (value === undefined) throw new Error(`${flag} needs a value`);
  if (flag === '--port') options.port = Number(value);
  else if (flag === '--host') options.host = value;
  else if (flag === '--web-root') options.webRoot = resolve(value);
  else if (flag === '--speed') options.speed = Number(value);
  else throw new Error(`unknown option ${flag} (--port, --host, --web-root, --speed)`);
}

const ROBOT = 'sim';
const RUN_ID = '1712000000123456789'; // beyond 2^53, as real run ids are
const T0_NS = 1712000000000000000n; // the robot's clock at the mock's start
const started = Date.now();
const elapsed = () => ((Date.now() - started) / 1000) * options.speed; // seconds of robot time
const ns = (seconds) => (T0_NS + BigInt(Math.round(seconds * 1e9))).toString();

// A small deterministic generator (mulberry32).
function random(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

// --- segments: a corridor floor and wall in 16 m pieces along x, sorted by x so they grow along it.
const SEGMENT_POINTS = 150000;
const CHUNKS = 6;
const CHUNK_S = 1.0; // one chunk per second
const segment_specs = [
  { segment_id: 0, version: 0, start_s: 0, x0: 0 },
  { segment_id: 1, version: 0, start_s: 2.5, x0: 16 },
  { segment_id: 2, version: 0, start_s: 5, x0: 32 },
  { segment_id: 0, version: 1, start_s: 20, x0: 0 }, // the first piece closed again
];
const clouds = new Map();

function cloud(spec) {
  const key = `${spec.segment_id}/${spec.version}`;
  if (clouds.has(key)) return clouds.get(key);
  const rnd = random(1 + spec.segment_id * 7 + spec.version * 101);
  const xs = Array.from({ length: SEGMENT_POINTS }, () => spec.x0 + 16 * rnd()).sort((a, b) => a - b);
  const positions = new Float32Array(3 * SEGMENT_POINTS);
  const colors = new Uint8Array(3 * SEGMENT_POINTS);
  xs.forEach((x, i) => {
    const wall = rnd() < 0.35;
    const y = wall ? 3 + 0.01 * rnd() : -1 + 4 * rnd();
    const z = wall ? 2.5 * rnd() : 0.01 * rnd();
    positions.set([x, y, z], 3 * i);
    const stripe = Math.floor(x / 2) % 2 === 0;
    const base = wall ? [90, 110, 150] : stripe ? [150, 140, 120] : [120, 115, 100];
    const tint = spec.version === 1 ? [30, -20, -20] : [0, 0, 0];
    colors.set(base.map((c, k) => Math.max(0, Math.min(255, c + tint[k] + 40 * (rnd() - 0.5)))), 3 * i);
  });
  const value = { positions, colors };
  clouds.set(key, value);
  return value;
}

function segments_now() {
  const t = elapsed();
  const out = [];
  for (const spec of segment_specs) {
    const chunks = Math.min(CHUNKS, Math.floor((t - spec.start_s) / CHUNK_S) + 1);
    if (chunks <= 0) continue;
    out.push({
      run_id: RUN_ID,
      segment_id: spec.segment_id,
      version: spec.version,
      points: Math.round((SEGMENT_POINTS * chunks) / CHUNKS),
      chunks_stored: chunks,
      chunk_count: CHUNKS,
      complete: chunks === CHUNKS,
      revision: chunks,
      T_world_segment: [1, 0, 0, spec.x0, 0, 1, 0, 0, 0, 0, 1, 0],
      spec,
    });
  }
  return out;
}

// --- the camera: walks along x at 0.8 m/s, 1.2 m high, looking along +x (OpenCV axes: x right,
// y down, z forward; the columns of R are these axes in the world).
const POSE_HZ = 10;
function camera_at(seconds) {
  const x = (0.8 * seconds) % 48;
  const y = 1.0 + 0.3 * Math.sin(seconds / 3);
  return [0, 0, 1, x, -1, 0, 0, y, 0, -1, 0, 1.2];
}

// --- keyframes, regions and commands.
const keyframe_specs = [1, 4, 9, 15].map((s) => ({ s, t_ns: ns(s), width: 640, height: 480 }));
const detections = [
  {
    detection_id: '7', segment_id: 0, keyframe_t_ns: keyframe_specs[0].t_ns, source: 'geometry', state: 'proposed',
    confidence: 0.83, box_px: [220, 180, 160, 90], center_world_m: [5, 2.8, 0.9], size_m: [1.2, 0.3, 0.4],
    q_world_box: [1, 0, 0, 0], seam_world_m: [[4.4, 2.9, 0.9], [5.6, 2.9, 0.9]], t_ns: keyframe_specs[0].t_ns,
  },
  {
    detection_id: '8', segment_id: 1, keyframe_t_ns: keyframe_specs[1].t_ns, source: 'model', state: 'confirmed',
    confidence: 0.64, box_px: [300, 240, 120, 120], center_world_m: [20, 2.7, 0.5], size_m: [0.6, 0.6, 0.6],
    q_world_box: [0.9239, 0, 0, 0.3827], seam_world_m: [[19.7, 2.7, 0.5], [20.3, 2.7, 0.5]], t_ns: keyframe_specs[1].t_ns,
  },
];
const commands = [];
let next_command = 1n;
let next_detection = 100;

function apply(command) {
  const c = command.body;
  const d = detections.find((x) => x.detection_id === String(c.detection_id));
  if (c.kind !== 'add' && !d) return refuse(command, `no welding region ${c.detection_id}`);
  if (c.kind === 'confirm') d.state = 'confirmed';
  else if (c.kind === 'reject') d.state = 'rejected';
  else if (c.kind === 'move') Object.assign(d, { center_world_m: c.center_world_m, size_m: c.size_m, q_world_box: c.q_world_box });
  else {
    const kf = keyframe_specs.find((k) => k.t_ns === String(c.keyframe_t_ns));
    if (!kf) return refuse(command, `no keyframe ${c.keyframe_t_ns}`);
    const T = camera_at(kf.s);
    const id = String(next_detection++);
    detections.push({
      detection_id: id, segment_id: -1, keyframe_t_ns: kf.t_ns, source: 'operator', state: 'confirmed', confidence: 1,
      box_px: c.box_px, center_world_m: [T[3] + 2, T[7], T[11]], size_m: [0.4, 0.4, 0.4], q_world_box: [1, 0, 0, 0],
      seam_world_m: [], t_ns: ns(elapsed()),
    });
    command.record.result_detection_id = id;
  }
  command.record.state = 'accepted';
}

function refuse(command, reason) {
  command.record.state = 'refused';
  command.record.reason = reason;
}

// A command body as hwr-ground checks it: an error text, or null.
function check_command(c) {
  if (typeof c !== 'object' || c === null) return 'command: the body is not a JSON object';
  if (c.robot !== ROBOT) return `command: unknown robot '${c.robot}'`;
  const id = (v) => (typeof v === 'string' && /^-?\d+$/.test(v)) || Number.isInteger(v);
  const numbers = (v, n) => Array.isArray(v) && v.length === n && v.every((x) => typeof x === 'number');
  if (['confirm', 'reject', 'move'].includes(c.kind)) {
    if (!id(c.detection_id)) return "command: 'detection_id' must be an integer (or one as a string)";
    if (c.kind === 'move' && !(numbers(c.center_world_m, 3) && numbers(c.size_m, 3) && numbers(c.q_world_box, 4)))
      return "command: move needs 'center_world_m' [3], 'size_m' [3] and 'q_world_box' [4]";
  } else if (c.kind === 'add') {
    if (!id(c.keyframe_t_ns)) return "command: 'keyframe_t_ns' must be an integer (or one as a string)";
    if (!numbers(c.box_px, 4)) return "command: 'box_px' must be an array of 4 numbers";
  } else return "command: 'kind' must be confirm, reject, move or add";
  return null;
}

// --- keyframe images: a 24-bit BMP (no encoder needed; the page loads any format an <img> can).
const images = new Map();
function keyframe_image(kf) {
  if (images.has(kf.t_ns)) return images.get(kf.t_ns);
  const { width: w, height: h } = kf;
  const row = Math.ceil((3 * w) / 4) * 4;
  const data = Buffer.alloc(54 + row * h);
  data.write('BM', 0);
  data.writeUInt32LE(data.length, 2);
  data.writeUInt32LE(54, 10);
  data.writeUInt32LE(40, 14);
  data.writeInt32LE(w, 18);
  data.writeInt32LE(-h, 22); // top-down rows
  data.writeUInt16LE(1, 26);
  data.writeUInt16LE(24, 28);
  data.writeUInt32LE(row * h, 34);
  for (let y = 0; y < h; ++y) {
    for (let x = 0; x < w; ++x) {
      const plate = x > 200 && x < 420 && y > 170 && y < 290;
      const v = plate ? 170 : 60 + ((x + y + kf.s * 40) % 64);
      const o = 54 + y * row + 3 * x;
      data[o] = plate ? 150 : v; // B
      data[o + 1] = plate ? 160 : v; // G
      data[o + 2] = plate ? 170 : v + 20; // R
    }
  }
  images.set(kf.t_ns, data);
  return data;
}

// --- the API.
function state() {
  const t = elapsed();
  const segments = segments_now();
  const poses = Math.floor(t * POSE_HZ) + 1;
  const bytes = segments.reduce((sum, s) => sum + s.chunks_stored * 41000, 0);
  const missing = segments.reduce((sum, s) => sum + s.chunk_count - s.chunks_stored, 0);
  for (const c of commands) if (c.record.state === 'pending' && Date.now() >= c.due_ms) apply(c);
  for (const d of detections) d.t_ns = ns(Math.floor(t)); // the robot republishes its list every second
  return {
    server: { t_ns: ns(t), out_dir: '/tmp/mock-ground', web_root: options.webRoot },
    robots: [
      {
        robot_id: ROBOT,
        run_id: RUN_ID,
        pose: { t_ns: ns(t), T_world_cam: camera_at(t), tracking: true, localized: false },
        trajectory_poses: poses,
        status: {
          t_ns: ns(Math.floor(t)),
          received_ns: ns(Math.floor(t)),
          tasks: [
            { name: 'camera', runs: Math.floor(t * 30), overruns: Math.floor(t / 7), slips: 0 },
            { name: 'imu', runs: Math.floor(t * 200), overruns: 0, slips: 0 },
            { name: 'stream', runs: Math.floor(t * 10), overruns: 0, slips: Math.floor(t / 20) },
          ],
          counters: { 'link.resends': Math.floor(t / 5), 'map.points': segments.reduce((s, x) => s + x.points, 0) },
        },
        link: {
          chunks_stored: segments.reduce((sum, s) => sum + s.chunks_stored, 0),
          bytes_stored: bytes,
          points_stored: segments.reduce((sum, s) => sum + s.points, 0),
          rate_bytes_s: missing > 0 ? 41000 : 0,
          missing_chunks: missing,
          robot_resends: Math.floor(t / 5),
          duplicates: Math.floor(t / 9),
          rejected: 0,
          last_chunk_age_s: missing > 0 ? (t % CHUNK_S) : t - 25,
        },
        segments: segments.map(({ spec, ...s }) => s),
        detections,
        commands: commands.map((c) => c.record),
        keyframes: keyframe_specs.filter((k) => k.s <= t).map(({ t_ns, width, height }) => ({ t_ns, width, height })),
      },
    ],
  };
}

function send_json(res, status, body) {
  res.writeHead(status, { 'Content-Type': 'application/json', 'Cache-Control': 'no-store' });
  res.end(JSON.stringify(body));
}

function get_segment(res, q) {
  const s = segments_now().find(
    (x) => x.run_id === q.get('run') && String(x.segment_id) === q.get('segment') && String(x.version) === q.get('version'),
  );
  if (!s) return send_json(res, 404, { error: 'segment: no such segment' });
  const { positions, colors } = cloud(s.spec);
  const total = s.points;
  const max = Number(q.get('max_points') || 0);
  const stride = max > 0 && total > max ? Math.ceil(total / max) : 1;
  const n = Math.ceil(total / stride);
  const body = Buffer.alloc(16 + 15 * n);
  body.write('HWRS', 0);
  body.writeUInt32LE(1, 4);
  body.writeUInt32LE(n, 8);
  body.writeUInt32LE(total, 12);
  for (let i = 0; i < n; ++i) {
    const j = i * stride;
    for (let k = 0; k < 3; ++k) {
      body.writeFloatLE(positions[3 * j + k], 16 + 12 * i + 4 * k);
      body[16 + 12 * n + 3 * i + k] = colors[3 * j + k];
    }
  }
  res.writeHead(200, { 'Content-Type': 'application/octet-stream', 'Cache-Control': 'no-store' });
  res.end(body);
}

function get_trajectory(res) {
  const n = Math.floor(elapsed() * POSE_HZ) + 1;
  const step = Math.max(1, Math.ceil(n / 20000));
  const t_ns = [];
  const xyz = [];
  for (let i = (n - 1) % step; i < n; i += step) {
    const T = camera_at(i / POSE_HZ);
    t_ns.push(ns(i / POSE_HZ));
    xyz.push([T[3], T[7], T[11]]);
  }
  send_json(res, 200, { robot_id: ROBOT, run_id: RUN_ID, t_ns, xyz });
}

function post_command(req, res) {
  let text = '';
  req.on('data', (chunk) => (text += chunk));
  req.on('end', () => {
    let body;
    try {
      body = JSON.parse(text);
    } catch {
      return send_json(res, 400, { error: 'command: the body is not a JSON object' });
    }
    const error = check_command(body);
    if (error) return send_json(res, 400, { error });
    const command_id = (BigInt(Date.now()) * 1000000n + next_command++).toString(); // realtime ns, as hwr-ground's
    commands.push({
      body,
      due_ms: Date.now() + 1000,
      record: {
        command_id, kind: body.kind, detection_id: String(body.detection_id ?? '0'), state: 'pending', reason: '',
        result_detection_id: String(body.detection_id ?? '0'), t_ns: ns(elapsed()),
      },
    });
    send_json(res, 200, { command_id });
  });
}

const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.svg': 'image/svg+xml', '.png': 'image/png' };

function get_static(res, path) {
  const file = normalize(join(options.webRoot, path === '/' ? 'index.html' : decodeURIComponent(path)));
  if (!file.startsWith(options.webRoot + sep) || !existsSync(file) || !statSync(file).isFile()) {
    res.writeHead(404, { 'Content-Type': 'text/plain' });
    return res.end(`not found (is the page built? toolchain/build-web.sh → ${options.webRoot})\n`);
  }
  res.writeHead(200, { 'Content-Type': TYPES[extname(file)] || 'application/octet-stream' });
  createReadStream(file).pipe(res);
}

const server = createServer((req, res) => {
  const url = new URL(req.url, 'http://mock');
  const q = url.searchParams;
  const robot_ok = () => q.get('robot') === ROBOT || (send_json(res, 404, { error: `no robot '${q.get('robot')}'` }), false);
  if (req.method === 'GET' && url.pathname === '/api/state') return send_json(res, 200, state());
  if (req.method === 'GET' && url.pathname === '/api/segment') return robot_ok() && get_segment(res, q);
  if (req.method === 'GET' && url.pathname === '/api/trajectory') return robot_ok() && get_trajectory(res);
  if (req.method === 'GET' && url.pathname === '/api/keyframe') {
    if (!robot_ok()) return;
    const kf = keyframe_specs.find((k) => k.t_ns === q.get('t_ns') && k.s <= elapsed());
    if (!kf) return send_json(res, 404, { error: `keyframe: no image of keyframe ${q.get('t_ns')}` });
    res.writeHead(200, { 'Content-Type': 'image/bmp', 'Cache-Control': 'no-store' });
    return res.end(keyframe_image(kf));
  }
  if (req.method === 'POST' && url.pathname === '/api/command') return post_command(req, res);
  if (url.pathname.startsWith('/api/')) return send_json(res, 404, { error: `no ${req.method} ${url.pathname}` });
  if (req.method === 'GET') return get_static(res, url.pathname);
  send_json(res, 405, { error: 'method not allowed' });
});

server.listen(options.port, options.host, () => {
  console.log(`mock: viewer at http://${options.host}:${server.address().port}/ (web root ${options.webRoot})`);
});
for (const signal of ['SIGINT', 'SIGTERM']) process.on(signal, () => process.exit(0));
