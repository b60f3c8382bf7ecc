// The side panels: link health, the scheduler, the detection list and the operator's commands.
// Rows carry data-* attributes the end-to-end test reads (docs/ground_viewer.md).

function text(tag, content, cls) {
  const e = document.createElement(tag);
  e.textContent = content;
  if (cls) e.className = cls;
  return e;
}

function rows(table, header, values) {
  table.replaceChildren();
  if (header) {
    const tr = document.createElement('tr');
    for (const h of header) tr.appendChild(text('th', h));
    table.appendChild(tr);
  }
  for (const row of values) {
    const tr = document.createElement('tr');
    for (const v of row) tr.appendChild(text('td', String(v)));
    table.appendChild(tr);
  }
}

function bytes_text(n) {
  if (n >= 1 << 20) return `${(n / (1 << 20)).toFixed(2)} MB`;
  if (n >= 1 << 10) return `${(n / (1 << 10)).toFixed(1)} kB`;
  return `${n} B`;
}

export function show_link(table, link, segments) {
  const complete = segments.filter((s) => s.complete).length;
  rows(table, null, [
    ['segments complete', `${complete} / ${segments.length}`],
    ['chunks stored', link.chunks_stored],
    ['points stored', link.points_stored.toLocaleString()],
    ['bytes stored', bytes_text(link.bytes_stored)],
    ['rate', `${bytes_text(Math.round(link.rate_bytes_s))}/s`],
    ['missing chunks', link.missing_chunks],
    ['robot resends', link.robot_resends < 0 ? 'unknown' : link.robot_resends],
    ['received twice', link.duplicates],
    ['rejected', link.rejected],
    ['last chunk', link.last_chunk_age_s < 0 ? 'none' : `${link.last_chunk_age_s.toFixed(1)} s ago`],
  ]);
}

export function show_status(tasks_table, counters_table, status) {
  if (!status) {
    rows(tasks_table, null, [['no status from the robot yet']]);
    counters_table.replaceChildren();
    return;
  }
  rows(tasks_table, ['task', 'runs', 'overruns', 'slips'], status.tasks.map((t) => [t.name, t.runs, t.overruns, t.slips]));
  rows(counters_table, null, Object.entries(status.counters));
}

// Keeps one row per item in container, in the items' order: rows are made once per key and then
// updated in place, so a button stays the same element while the lists refresh under the pointer.
function keyed_rows(container, items, key_of, make, fill, empty_text) {
  if (items.length === 0) {
    container.replaceChildren(text('div', empty_text, 'empty'));
    return;
  }
  container.querySelector(':scope > .empty')?.remove();
  const old = new Map([...container.children].map((row) => [row.dataset.key, row]));
  items.forEach((item, i) => {
    const key = String(key_of(item));
    let row = old.get(key);
    old.delete(key);
    if (!row) {
      row = make();
      row.dataset.key = key;
    }
    fill(row, item);
    if (container.children[i] !== row) container.insertBefore(row, container.children[i] ?? null);
  });
  for (const row of old.values()) row.remove();
}

function set_text(element, content, cls) {
  if (element.textContent !== content) element.textContent = content;
  if (cls != null && element.className !== cls) element.className = cls;
}

// One row per detection: id, source, confidence, state, and the operator's buttons.
// on_action(action, detection) for confirm, reject, edit; on_select(detection) for a click on the row.
export function show_detections(container, detections, on_action, on_select) {
  const make = () => {
    const row = document.createElement('div');
    row.append(text('span', ''), text('span', ''));
    const buttons = document.createElement('div');
    for (const action of ['confirm', 'reject', 'edit']) {
      const b = text('button', action[0].toUpperCase() + action.slice(1));
      b.type = 'button';
      b.dataset.action = action;
      b.addEventListener('click', (event) => {
        event.stopPropagation();
        on_action(action, row.detection);
      });
      buttons.appendChild(b);
    }
    row.appendChild(buttons);
    row.addEventListener('click', () => on_select(row.detection));
    return row;
  };
  const fill = (row, d) => {
    row.detection = d;
    row.dataset.detectionId = d.detection_id;
    row.dataset.state = d.state;
    const [tag, label, buttons] = row.children;
    set_text(tag, d.state, `tag state-${d.state}`);
    set_text(label, ` #${d.detection_id} ${d.source} ${(100 * d.confidence).toFixed(0)} %`);
    for (const b of buttons.children) {
      b.disabled = (b.dataset.action === 'confirm' && d.state === 'confirmed') || (b.dataset.action === 'reject' && d.state === 'rejected');
    }
  };
  keyed_rows(container, detections, (d) => d.detection_id, make, fill, 'no welding regions yet');
}

// The operator's commands, newest first, each with the robot's answer.
export function show_commands(container, commands) {
  const make = () => {
    const row = document.createElement('div');
    row.append(text('span', ''), text('span', ''));
    return row;
  };
  const fill = (row, c) => {
    row.dataset.commandId = c.command_id;
    row.dataset.state = c.state;
    const added = c.state === 'accepted' ? `→ detection ${c.result_detection_id}` : 'a new region';
    const target = c.kind === 'add' ? added : `detection ${c.detection_id}`;
    set_text(row.children[0], c.state, `tag state-${c.state}`);
    set_text(row.children[1], ` ${c.kind} ${target}${c.reason ? ` (${c.reason})` : ''}`);
  };
  keyed_rows(container, [...commands].reverse(), (c) => c.command_id, make, fill, 'none sent');
}
