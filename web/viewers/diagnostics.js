// diagnostic_msgs/DiagnosticArray: a status table, the worst on top (error, stale, warning, ok; then by name),
// each status with its level, name, message and hardware id, its key/values behind a click. Statuses are kept by
// name across messages (aggregators publish some at a time); one not heard for STALE_S is marked stale.
const LEVELS = { 0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE' };
const WORST_FIRST = { 2: 0, 3: 1, 1: 2, 0: 3 };
const STALE_S = 10;
const REFRESH_MS = 250;

export class DiagnosticsViewer {
  static subscription = { throttle_rate: 100, queue_length: 5 };

  constructor(element) {
    element.innerHTML = `<p class="diag-summary" aria-live="off">waiting for diagnostics…</p>
      <div class="scroll"><table class="diag-table">
        <thead><tr><th>Level</th><th>Name</th><th>Message</th><th>Hardware</th></tr></thead><tbody></tbody>
      </table></div>`;
    this.summary = element.querySelector('.diag-summary');
    this.body = element.querySelector('tbody');
    this.body.addEventListener('click', event => {
      const row = event.target.closest('tr.diag-status');
      if (!row) return;
      if (this.open.has(row.dataset.name)) this.open.delete(row.dataset.name);
      else this.open.add(row.dataset.name);
      this.dirty = true;
    });
    this.statuses = new Map();  // name -> { status, heard (ms) }
    this.open = new Set();  // names whose values are shown
    this.dirty = false;
    this.timer = setInterval(() => this.render(), REFRESH_MS);
  }

  draw(array) {
    const now = performance.now();
    for (const status of array.status ?? []) this.statuses.set(status.name ?? '', { status, heard: now });
    this.dirty = true;
  }

  render() {
    const now = performance.now();
    let changed = this.dirty;
    const rows = [...this.statuses].map(([name, { status, heard }]) => {
      const stale = now - heard > STALE_S * 1000;
      if (stale) changed = true;
      return { name, status, level: stale ? 3 : status.level };
    });
    if (!changed) return;
    this.dirty = false;
    rows.sort((a, b) => (WORST_FIRST[a.level] ?? -1) - (WORST_FIRST[b.level] ?? -1) || a.name.localeCompare(b.name));
    const made = [];
    for (const { name, status, level } of rows) {
      const row = document.createElement('tr');
      row.className = `diag-status diag-${(LEVELS[level] ?? 'unknown').toLowerCase()}`;
      row.dataset.name = name;
      row.dataset.level = String(level);
      row.innerHTML = '<td class="lvl"></td><td class="name"></td><td></td><td class="muted"></td>';
      [row.cells[0].textContent, row.cells[1].textContent, row.cells[2].textContent, row.cells[3].textContent] =
        [LEVELS[level] ?? String(level), name, status.message ?? '', status.hardware_id ?? ''];
      row.title = 'Show its values';
      made.push(row);
      if (this.open.has(name)) {
        const values = document.createElement('tr');
        values.className = 'diag-values';
        values.innerHTML = '<td></td><td colspan="3"><dl></dl></td>';
        values.querySelector('dl').append(...(status.values ?? []).flatMap(({ key, value }) => {
          const [dt, dd] = [document.createElement('dt'), document.createElement('dd')];
          [dt.textContent, dd.textContent] = [key, value];
          return [dt, dd];
        }));
        made.push(values);
      }
    }
    this.body.replaceChildren(...made);
    const counts = [2, 3, 1, 0].map(level => [level, rows.filter(r => r.level === level).length])
      .filter(([, n]) => n).map(([level, n]) => `${n} ${LEVELS[level]}`);
    this.summary.textContent = `${rows.length} statuses: ${counts.join(' · ') || 'none'}`;
  }

  close() {
    clearInterval(this.timer);
  }
}
