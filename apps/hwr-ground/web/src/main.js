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

// Resolves to whether hwr-ground took the command (the commands panel then shows its state).
async function send(command) {
  $('command-error').textContent = '';
  try {
    const id = await post_command({ robot: robot_id, ...command });
    document.body.dataset.lastCommandId = id;
    return true;
  } catch (error) {
    $('command-error').textContent = `${command.kind}: ${error.message}`;
    return false;
  }
}

function on_detection_action(action, d) {
  if (action === 'edit') {
    const form = $('edit-form');
    form.hidden = false;
    form.dataset.editId = d.detection_id;  // not data-detection-id: that names the list's rows
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
    detection_id: form.dataset.editId,
    center_world_m: numbers(['cx', 'cy', 'cz']),
    size_m: numbers(['sx', 'sy', 'sz']),
    q_world_box: JSON.parse(form.dataset.q),
  });
  form.hidden = true;
});
$('edit-form').querySelector('[data-action="cancel-move"]').addEventListener('click', () => ($('edit-form').hidden = true));

$('add-region').addEventListener('click', () => {
  if (!keyframes.drawn || !keyframes.keyframe) return;
  send({ kind: 'add', keyframe_t_ns: keyframes.keyframe.t_ns, box_px: keyframes.drawn }).then((sent) => sent && keyframes.clear());
});

$('robot').addEventListener('change', (event) => {
  robot_id = event.target.value;
  for (const key of [...(scene?.segments.keys() ?? [])]) scene.remove_segment(key);
  trajectory_poses = -1;
});

// The newest keyframe is shown until the operator picks another one or starts drawing on it.
let keyframe_chosen = false;
$('keyframe').addEventListener('change', () => {
  keyframe_chosen = $('keyframe').selectedIndex > 0;
  show_keyframe();
});
$('keyframe-canvas').addEventListener('pointerdown', () => (keyframe_chosen = true));
$('frame-all').addEventListener('click', () => scene?.frame_all());
$('frame-all').disabled = scene == null;

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

// Options newest first, named by their age relative to the newest and the regions drawn on them.
function update_keyframe_select(list, detections) {
  const select = $('keyframe');
  const newest_first = [...list].reverse();
  const values = newest_first.map((k) => k.t_ns);
  const label = (k) => {
    const regions = detections.filter((d) => d.keyframe_t_ns === k.t_ns).length;
    let age_s = NaN;
    try {
      age_s = Number(BigInt(newest_first[0].t_ns) - BigInt(k.t_ns)) * 1e-9;
    } catch {
      // not an integer: named by its time stamp
    }
    const name = age_s === 0 ? 'newest keyframe' : Number.isFinite(age_s) ? `${age_s.toFixed(1)} s earlier` : `keyframe ${k.t_ns}`;
    return name + (regions ? ` · ${regions} region(s)` : '');
  };
  const labels = newest_first.map(label);
  if ([...select.options].map((o) => o.value + o.text).join() === values.map((v, i) => v + labels[i]).join()) return;
  const keep = select.value;
  select.replaceChildren(...newest_first.map((k, i) => new Option(labels[i], k.t_ns)));
  select.value = keyframe_chosen && values.includes(keep) ? keep : values[0] ?? '';
}

const RETRY_MS = 5000;
const failed = new Map();  // segment key -> when its last fetch failed

async function load_segment(segment, full) {
  const key = key_of(segment);
  if (loading.has(key) || performance.now() - (failed.get(key) ?? -RETRY_MS) < RETRY_MS) return;
  loading.add(key);
  try {
    const data = await fetch_segment(segment.robot_id, segment, full ? 0 : THINNED_POINTS);
    if (segment.robot_id !== robot_id) return;  // the operator picked another robot meanwhile
    scene.set_segment(key, segment.revision, data, full || data.count === data.total);
    failed.delete(key);
    // The newer version is drawn: the older ones of that segment go.
    for (const k of [...scene.segments.keys()]) {
      const [run, id, version] = k.split('/');
      if (run === String(segment.run_id) && id === String(segment.segment_id) && Number(version) < segment.version)
        scene.remove_segment(k);
    }
    show_segments_drawn();
  } catch (error) {
    failed.set(key, performance.now());
    $('view-message').textContent = `segment ${key}: ${error.message}`;
  } finally {
    loading.delete(key);
  }
}

function show_segments_drawn() {
  document.body.dataset.segmentsDrawn = String(scene ? scene.segments_drawn() : 0);
}

// Each segment's newest version is fetched thinned when it is new or its points changed (at full
// resolution when the view is zoomed in on it), and again in full once the view zooms in on it. An
// older version stays drawn until the newer one has arrived.
function update_segments(robot) {
  if (!scene) return;
  const newest = new Map();
  for (const s of robot.segments) {
    const prev = newest.get(s.segment_id);
    if (!prev || s.version > prev.version) newest.set(s.segment_id, { ...s, robot_id: robot.robot_id });
  }
  // A segment no longer listed goes (a new run); an older version goes once its successor is drawn.
  const listed = new Set(robot.segments.map((s) => `${s.run_id}/${s.segment_id}`));
  for (const key of [...scene.segments.keys()]) {
    if (!listed.has(key.split('/').slice(0, 2).join('/'))) scene.remove_segment(key);
  }
  for (const s of newest.values()) {
    const key = key_of(s);
    const drawn = scene.segments.get(key);
    if (!drawn || drawn.revision !== s.revision) load_segment(s, drawn != null && scene.zoomed_in_on(key));
  }
  for (const key of scene.segments_to_refine()) {
    const s = [...newest.values()].find((x) => key_of(x) === key);
    if (s) load_segment(s, true);
  }
  show_segments_drawn();
}

async function update_trajectory(robot) {
  if (robot.trajectory_poses === 0 && trajectory_poses !== 0) {
    scene?.set_trajectory([]);  // a new run without poses yet
    trajectory_poses = 0;
  }
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

function show_state(state) {
  update_robot_select(state.robots);
  const robot = state.robots.find((r) => r.robot_id === robot_id);
  if (!robot) {
    $('pose-text').textContent = 'no robot has sent anything yet';
    return;
  }
  last_robot = robot;
  update_segments(robot);
  update_trajectory(robot);
  show_pose(robot.pose);
  // Only when they change; the rows are updated in place (panels.js), so a click is never lost.
  if (changed('detections', robot.detections)) {
    scene?.set_detections(robot.detections);
    show_detections($('detections'), robot.detections, on_detection_action, (d) => scene?.frame_detection(d));
    document.body.dataset.detectionsDrawn = String(robot.detections.length);
  }
  if (changed('commands', robot.commands)) show_commands($('commands'), robot.commands);
  show_link($('link'), robot.link, robot.segments);
  show_status($('tasks'), $('counters'), robot.status);
  update_keyframe_select(robot.keyframes, robot.detections);
  show_keyframe();
}

// Every POLL_MS, also after failures: a restarted hwr-ground is picked up again by itself.
async function poll() {
  let state = null;
  try {
    state = await fetch_state();
  } catch (error) {
    $('connection').textContent = `ground station unreachable (${error.message}); retrying`;
    $('connection').className = 'bad';
  }
  if (state) {
    try {
      show_state(state);
      $('connection').textContent = 'ground station connected';
      $('connection').className = 'good';
      document.body.dataset.stateRevision = String(++revision);
    } catch (error) {
      console.error(error);
      $('connection').textContent = `ground station connected; the page failed to show its state: ${error.message}`;
      $('connection').className = 'bad';
    }
  }
  setTimeout(poll, POLL_MS);
}

poll();
