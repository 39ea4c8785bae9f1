// Live plots on uPlot: a window of the newest samples, redrawn at most once a frame.
"use strict";

const WINDOW_POINTS = 1000; // 10 s at the default 100 samples/s

const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"];

/** One plot: `labels` are the series' names; `push(t, values)` adds a sample. */
class LivePlot {
  constructor(el, title, unit, labels) {
    this.el = el;
    this.data = [[]].concat(labels.map(() => []));
    this.dirty = false;
    const width = Math.max(320, el.clientWidth || 480);
    this.plot = new uPlot({
      title: title,
      width: width,
      height: 140,
      legend: { live: false },
      cursor: { show: false },
      scales: { x: { time: false } },
      axes: [{ label: "t (s)", size: 32 }, { label: unit, size: 56 }],
      series: [{ label: "t" }].concat(labels.map((l, i) => ({
        label: l, stroke: COLORS[i % COLORS.length], width: 1.3, points: { show: false },
      }))),
    }, this.data, el);
  }

  push(t, values) {
    this.data[0].push(t);
    for (let i = 0; i < values.length && i + 1 < this.data.length; i++) {
      this.data[i + 1].push(values[i]);
    }
    if (this.data[0].length > WINDOW_POINTS) {
      for (const s of this.data) s.splice(0, s.length - WINDOW_POINTS);
    }
    this.dirty = true;
  }

  clear() {
    for (const s of this.data) s.length = 0;
    this.dirty = true;
  }

  draw() {
    if (this.dirty) {
      this.plot.setData(this.data);
      this.dirty = false;
    }
  }
}

/** The four plots of the live panel. */
function makePlots() {
  const joints = ["q1", "q2", "q3", "q4", "q5", "q6"];
  return {
    q: new LivePlot(document.getElementById("plot-q"), "Joint positions", "rad", joints),
    p: new LivePlot(document.getElementById("plot-p"), "Tool position", "m", ["x", "y", "z"]),
    f: new LivePlot(document.getElementById("plot-f"), "Wrench", "N, N·m", ["fx", "fy", "fz", "tx", "ty", "tz"]),
    dt: new LivePlot(document.getElementById("plot-dt"), "Loop timing: sample interval", "ms", ["interval"]),
  };
}
