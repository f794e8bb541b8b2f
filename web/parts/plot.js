// Plot: numeric fields of open topics over the last 30 s, several series at once (uPlot, from npm, served
// locally). Click a number in an open topic's tree to add it; Pause holds the picture; the axes autoscale.
import uPlot from '../vendor/uPlot.esm.js';
import { readAddress, keepInAddress } from '../address.js';

const WINDOW_S = 30;
const REDRAW_MS = 100;
const COLOURS = ['#3fd68c', '#ffc247', '#ff6b7d', '#6b79ff', '#4dd0e1', '#f06292'];
const PLOT_PARAM = 'plot';  // ?plot=/turtle1/pose:x&plot=/odom:pose.pose.position.x, kept in the page's address

export class Plot {
  constructor(root) {
    this.root = root;
    root.innerHTML = `
      <div class="row"><strong>Plot</strong> <small class="muted">last ${WINDOW_S} s · click a number in a topic to add it</small>
        <button type="button" class="plot-pause">Pause</button><button type="button" class="plot-clear">Clear</button></div>
      <div class="plot-area"></div>
      <ul class="plot-series"></ul>`;
    this.area = root.querySelector('.plot-area');
    this.legend = root.querySelector('.plot-series');
    this.pauseButton = root.querySelector('button.plot-pause');
    this.series = [];  // {topic, path, label, points: [[t, v]]}
    this.paused = false;
    this.chart = null;
    this.pauseButton.addEventListener('click', () => {
      this.paused = !this.paused;
      this.pauseButton.textContent = this.paused ? 'Resume' : 'Pause';
    });
    root.querySelector('button.plot-clear').addEventListener('click', () => {
      this.series = [];
      this.rebuild();
    });
    new ResizeObserver(() => this.chart?.setSize(this.size())).observe(this.area);
    setInterval(() => this.paused || this.redraw(), REDRAW_MS);
    for (const kept of readAddress(PLOT_PARAM)) {
      const [, topic, path] = /^([^:]+):(.+)$/.exec(kept) ?? [];  // (ROS names hold no ':', field paths no '.')
      if (topic) this.add(topic, path.split('.'));
    }
  }

  add(topic, path) {
    const label = `${topic} ${path.join('.')}`;
    if (this.series.some(s => s.label === label)) return;
    this.series.push({ topic, path, label, points: [] });
    this.rebuild();
  }

  // Every message of an open topic: each series of that topic takes its value.
  push(topic, message) {
    const now = performance.now() / 1000;
    for (const series of this.series) {
      if (series.topic !== topic) continue;
      const value = series.path.reduce((v, key) => (v === undefined || v === null ? undefined : v[key]), message);
      if (typeof value !== 'number') continue;
      series.points.push([now, value]);
      while (series.points.length && series.points[0][0] < now - WINDOW_S) series.points.shift();
    }
  }

  size() {
    return { width: Math.max(200, this.area.clientWidth), height: 220 };
  }

  rebuild() {
    this.chart?.destroy();
    this.chart = null;
    this.root.hidden = !this.series.length;
    keepInAddress(PLOT_PARAM, this.series.map(s => `${s.topic}:${s.path.join('.')}`));
    this.legend.replaceChildren(...this.series.map((series, i) => {
      const item = document.createElement('li');
      item.innerHTML = '<span class="swatch"></span><code></code> <button type="button" class="link">remove</button>';
      item.firstChild.style.background = COLOURS[i % COLOURS.length];
      item.children[1].textContent = series.label;
      item.lastChild.addEventListener('click', () => {
        this.series.splice(this.series.indexOf(series), 1);
        this.rebuild();
      });
      return item;
    }));
    if (!this.series.length) return;
    const options = {
      ...this.size(),
      legend: { show: false },
      scales: { x: { time: false } },
      axes: [{ stroke: '#9aa6c8', grid: { stroke: '#2a355a' }, label: 's (now = 0)' },
        { stroke: '#9aa6c8', grid: { stroke: '#2a355a' } }],
      series: [{}, ...this.series.map((s, i) => ({ label: s.label, stroke: COLOURS[i % COLOURS.length], width: 2 }))],
    };
    this.chart = new uPlot(options, this.data(), this.area);
  }

  // Columns on one time axis (seconds before now); each series' points placed at their own times.
  data() {
    const now = performance.now() / 1000;
    const times = [...new Set(this.series.flatMap(s => s.points.map(([t]) => t)))].sort((a, b) => a - b);
    const index = new Map(times.map((t, i) => [t, i]));
    const columns = this.series.map(s => {
      const column = new Array(times.length).fill(null);
      for (const [t, v] of s.points) column[index.get(t)] = v;
      return column;
    });
    return [times.map(t => t - now), ...columns];
  }

  redraw() {
    if (this.chart) this.chart.setData(this.data());
  }
}
