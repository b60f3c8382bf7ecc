// The hwr-ground HTTP API (docs/ground_viewer.md). 64-bit ids arrive as strings and go back as such.
// Every request has a time limit, so a ground station that stops answering shows as unreachable
// instead of stalling the poll loop.

const TIMEOUT_MS = 5000;
const SEGMENT_TIMEOUT_MS = 120000;  // a full-resolution segment can be tens of MB

function get(url, timeout_ms = TIMEOUT_MS) {
  return fetch(url, { cache: 'no-store', signal: AbortSignal.timeout(timeout_ms) });
}

async function json_or_error(response) {
  const body = await response.json().catch(() => ({}));
  if (!response.ok) throw new Error(body.error || `${response.status} ${response.statusText}`);
  return body;
}

export async function fetch_state() {
  return json_or_error(await get('./api/state'));
}

export async function fetch_trajectory(robot) {
  return json_or_error(await get(`./api/trajectory?robot=${encodeURIComponent(robot)}`));
}

// A segment's points: {positions: Float32Array (x y z, world frame, metres), colors: Uint8Array
// (r g b), count, total}. Binary layout: "HWRS", uint32 format, n, total, n*3 float32, n*3 uint8.
export async function fetch_segment(robot, segment, max_points) {
  const q = new URLSearchParams({
    robot,
    run: segment.run_id,
    segment: String(segment.segment_id),
    version: String(segment.version),
    max_points: String(max_points),
  });
  const response = await get(`./api/segment?${q}`, SEGMENT_TIMEOUT_MS);
  if (!response.ok) await json_or_error(response);
  const buffer = await response.arrayBuffer();
  if (buffer.byteLength < 16) throw new Error('segment: body shorter than its header');
  const header = new DataView(buffer, 0, 16);
  const magic = String.fromCharCode(...new Uint8Array(buffer, 0, 4));
  if (magic !== 'HWRS' || header.getUint32(4, true) !== 1) throw new Error('segment: not an HWRS format 1 body');
  const count = header.getUint32(8, true);
  const total = header.getUint32(12, true);
  if (buffer.byteLength !== 16 + 15 * count) throw new Error('segment: truncated body');
  return {
    positions: new Float32Array(buffer, 16, 3 * count),
    colors: new Uint8Array(buffer, 16 + 12 * count, 3 * count),
    count,
    total,
  };
}

export function keyframe_url(robot, t_ns) {
  return `./api/keyframe?robot=${encodeURIComponent(robot)}&t_ns=${encodeURIComponent(t_ns)}`;
}

// Sends an operator command; resolves to the command id (a string) or throws with the server's reason.
export async function post_command(command) {
  const response = await fetch('./api/command', {
    method: 'POST',
    headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify(command),
    signal: AbortSignal.timeout(TIMEOUT_MS),
  });
  return (await json_or_error(response)).command_id;
}
