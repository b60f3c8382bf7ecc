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

// One row per detection: id, source, confidence, state, and the operator's buttons.
// on_action(action, detection) for confirm, reject, edit; on_select(detection) for a click on the row.
export function show_detections(container, detections, on_action, on_select) {
  container.replaceChildren();
  if (detections.length === 0) container.appendChild(text('div', 'no welding regions yet'));
  for (const d of detections) {
    const row = document.createElement('div');
    row.dataset.detectionId = d.detection_id;
    row.dataset.state = d.state;
    row.appendChild(text('span', d.state, `tag state-${d.state}`));
    row.appendChild(text('span', ` #${d.detection_id} ${d.source} ${(100 * d.confidence).toFixed(0)} %`));
    const buttons = document.createElement('div');
    for (const action of ['confirm', 'reject', 'edit']) {
      const b = text('button', action[0].toUpperCase() + action.slice(1));
      b.type = 'button';
      b.dataset.action = action;
      b.addEventListener('click', (event) => {
        event.stopPropagation();
        on_action(action, d);
      });
      buttons.appendChild(b);
    }
    row.appendChild(buttons);
    row.addEventListener('click', () => on_select(d));
    container.appendChild(row);
  }
}

export function show_commands(container, commands) {
  container.replaceChildren();
  if (commands.length === 0) container.appendChild(text('div', 'none sent'));
  for (const c of [...commands].reverse()) {
    const row = document.createElement('div');
    row.dataset.commandId = c.command_id;
    row.dataset.state = c.state;
    row.appendChild(text('span', c.state, `tag state-${c.state}`));
    const target = c.kind === 'add' ? `→ detection ${c.result_detection_id}` : `detection ${c.detection_id}`;
    row.appendChild(text('span', ` ${c.kind} ${target}${c.reason ? ` (${c.reason})` : ''}`));
    container.appendChild(row);
  }
}
