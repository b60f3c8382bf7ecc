// hwr-ground's viewer: polls the ground station's state (docs/ground_viewer.md) and draws it; the
// operator's buttons send commands through it. The page keeps no state of its own, so a reload or a
// restart of hwr-ground loses nothing.
import { fetch_segment, fetch_state, fetch_trajectory, keyframe_url, post_command } from './api.js';
import { KeyframeCanvas } from './keyframe_draw.js';
import { show_commands, show_detections, show_link, show_status } from './panels.js';
import { MapScene } from './scene.js';

const POLL_MS = 500;
const TRAJECTORY_MS = 2000;
const THINNED_POINTS = 60000;

const $ = (id) => document.getElementById(id);
let scene = null;
try {
  scene = new MapScene($('view'));
} catch (error) {
  $('view-message').textContent = `3D view unavailable (WebGL: ${error.message}); the panels still work`;
}

let robot_id = null;
let revision = 0;
let last_robot = null;        // the robot's part of the last state
const loading = new Set();    // segment keys being fetched
let last_trajectory_ms = 0;
let trajectory_poses = -1;

const shown = new Map();  // panel -> the JSON it shows
function changed(panel, value) {
  const text = JSON.stringify([robot_id, value]);
  if (shown.get(panel) === text) return false;
  shown.set(panel, text);
  return true;
}

const key_of = (s) => `${s.run_id}/${s.segment_id}/${s.version}`;

const keyframes = new KeyframeCanvas($('keyframe-canvas'), (box) => {
  $('add-region').disabled = box == null;
  $('drawn-box').textContent = box ? `x ${box[0]} y ${box[1]} w ${box[2]} h ${box[3]} px` : 'drag a rectangle on the image';
});

async function send(command) {
  $('command-error').textContent = '';
  try {
    const id = await post_command({ robot: robot_id, ...command });
    document.body.dataset.lastCommandId = id;
  } catch (error) {
    $('command-error').textContent = error.message;
  }
}

function on_detection_action(action, d) {
  if (action === 'edit') {
    const form = $('edit-form');
    form.hidden = false;
    form.dataset.detectionId = d.detection_id;
    form.dataset.q = JSON.stringify(d.q_world_box);
    $('edit-id').textContent = d.detection_id;
    ['cx', 'cy', 'cz'].forEach((n, i) => (form.elements[n].value = d.center_world_m[i].toFixed(3)));
    ['sx', 'sy', 'sz'].forEach((n, i) => (form.elements[n].value = d.size_m[i].toFixed(3)));
    return;
  }
  send({ kind: action, detection_id: d.detection_id });
}

$('edit-form').addEventListener('submit', (event) => {
  event.preventDefault();
  const form = event.target;
  const numbers = (names) => names.map((n) => Number(form.elements[n].value));
  send({
    kind: 'move',
    detection_id: form.dataset.detectionId,
    center_world_m: numbers(['cx', 'cy', 'cz']),
    size_m: numbers(['sx', 'sy', 'sz']),
    q_world_box: JSON.parse(form.dataset.q),
  });
  form.hidden = true;
});
$('edit-form').querySelector('[data-action="cancel-move"]').addEventListener('click', () => ($('edit-form').hidden = true));

$('add-region').addEventListener('click', () => {
  if (!keyframes.drawn || !keyframes.keyframe) return;
  send({ kind: 'add', keyframe_t_ns: keyframes.keyframe.t_ns, box_px: keyframes.drawn });
});

$('robot').addEventListener('change', (event) => {
  robot_id = event.target.value;
  for (const key of [...(scene?.segments.keys() ?? [])]) scene.remove_segment(key);
  trajectory_poses = -1;
});

$('keyframe').addEventListener('change', () => show_keyframe());

function show_keyframe() {
  if (!last_robot) return;
  const t = $('keyframe').value;
  const kf = last_robot.keyframes.find((k) => k.t_ns === t) ?? null;
  const boxes = last_robot.detections.filter((d) => d.keyframe_t_ns === t);
  keyframes.show(kf, kf ? keyframe_url(robot_id, kf.t_ns) : null, boxes);
}

function update_robot_select(robots) {
  const select = $('robot');
  const ids = robots.map((r) => r.robot_id);
  if ([...select.options].map((o) => o.value).join() !== ids.join()) {
    select.replaceChildren(...ids.map((id) => new Option(id, id)));
  }
  if (!ids.includes(robot_id)) robot_id = ids[0] ?? null;
  select.value = robot_id ?? '';
}

function update_keyframe_select(list) {
  const select = $('keyframe');
  const newest_first = [...list].reverse();
  const values = newest_first.map((k) => k.t_ns);
  if ([...select.options].map((o) => o.value).join() === values.join()) return;
  const keep = select.value;
  select.replaceChildren(...newest_first.map((k) => new Option(`keyframe ${(Number(k.t_ns) * 1e-9).toFixed(2)} s`, k.t_ns)));
  select.value = values.includes(keep) ? keep : values[0] ?? '';
}

async function load_segment(segment, full) {
  const key = key_of(segment);
  if (loading.has(key)) return;
  loading.add(key);
  try {
    const data = await fetch_segment(robot_id, segment, full ? 0 : THINNED_POINTS);
    scene.set_segment(key, segment.revision, data, full || data.count === data.total);
  } catch (error) {
    $('view-message').textContent = `segment ${key}: ${error.message}`;
  } finally {
    loading.delete(key);
  }
}

function update_segments(segments) {
  if (!scene) return;
  const wanted = new Map();
  // Only the newest version of each segment is drawn.
  for (const s of segments) {
    const prev = wanted.get(s.segment_id);
    if (!prev || s.version > prev.version) wanted.set(s.segment_id, s);
  }
  const keys = new Set([...wanted.values()].map(key_of));
  for (const key of [...scene.segments.keys()]) if (!keys.has(key)) scene.remove_segment(key);
  for (const s of wanted.values()) {
    const drawn = scene.segments.get(key_of(s));
    if (!drawn || drawn.revision !== s.revision) load_segment(s, drawn?.full ?? false);
  }
  for (const key of scene.segments_to_refine()) {
    const s = [...wanted.values()].find((x) => key_of(x) === key);
    if (s) load_segment(s, true);
  }
  let drawn = 0;
  for (const s of scene.segments.values()) if (s.points.geometry.attributes.position.count > 0) ++drawn;
  document.body.dataset.segmentsDrawn = String(drawn);
}

async function update_trajectory(robot) {
  const now = performance.now();
  if (robot.trajectory_poses === 0 || robot.trajectory_poses === trajectory_poses || now - last_trajectory_ms < TRAJECTORY_MS)
    return;
  last_trajectory_ms = now;
  try {
    const t = await fetch_trajectory(robot.robot_id);
    trajectory_poses = robot.trajectory_poses;
    scene?.set_trajectory(t.xyz);
  } catch {
    // shown again on the next poll
  }
}

function show_pose(pose) {
  scene?.set_pose(pose ? pose.T_world_cam : null);
  if (!pose) {
    $('pose-text').textContent = 'no pose yet';
    return;
  }
  const T = pose.T_world_cam;
  $('pose-text').textContent =
    `camera at (${T[3].toFixed(2)}, ${T[7].toFixed(2)}, ${T[11].toFixed(2)}) m` +
    (pose.tracking ? '' : ', tracking lost') + (pose.localized ? ', in the prior map' : '');
}

async function poll() {
  try {
    const state = await fetch_state();
    $('connection').textContent = 'ground station connected';
    $('connection').className = 'good';
    update_robot_select(state.robots);
    const robot = state.robots.find((r) => r.robot_id === robot_id);
    if (robot) {
      last_robot = robot;
      update_segments(robot.segments);
      update_trajectory(robot);
      show_pose(robot.pose);
      // Redrawn only when they change: a row rebuilt under the operator's click would lose it.
      if (changed('detections', robot.detections)) {
        scene?.set_detections(robot.detections);
        show_detections($('detections'), robot.detections, on_detection_action, (d) => scene?.frame_detection(d));
        document.body.dataset.detectionsDrawn = String(robot.detections.length);
      }
      if (changed('commands', robot.commands)) show_commands($('commands'), robot.commands);
      show_link($('link'), robot.link, robot.segments);
      show_status($('tasks'), $('counters'), robot.status);
      update_keyframe_select(robot.keyframes);
      show_keyframe();
    }
    document.body.dataset.stateRevision = String(++revision);
  } catch (error) {
    $('connection').textContent = `ground station unreachable (${error.message}); retrying`;
    $('connection').className = 'bad';
  } finally {
    setTimeout(poll, POLL_MS);
  }
}

poll();
