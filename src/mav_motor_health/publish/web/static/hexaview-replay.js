/* The hexacopter view at any moment of a replayed flight, with a time slider (needs hexaview.js).
 *
 * Reads the JSON in <script type="application/json" id="<root id>-data">:
 *   {layout, states, t_start_s, t_end_s, timelines: {"4": [[t_s, "NORMAL"], [85.2, "F3.1"], ...]}}
 * and mounts into the element with the root id. Several fragments can share a page.
 */
(function (global) {
  "use strict";
  if (global.MmhHexaReplay) {
    return;
  }

  /* Index of the last change at or before t, or -1. */
  function lastAtOrBefore(changes, t) {
    let lo = 0;
    let hi = changes.length - 1;
    let found = -1;
    while (lo <= hi) {
      const mid = (lo + hi) >> 1;
      if (changes[mid][0] <= t) {
        found = mid;
        lo = mid + 1;
      } else {
        hi = mid - 1;
      }
    }
    return found;
  }

  function mount(rootId) {
    const root = document.getElementById(rootId);
    const data = JSON.parse(document.getElementById(rootId + "-data").textContent);
    const view = global.MmhHexaView.create(root.querySelector(".mmh-replay-view"), {
      layout: data.layout,
      states: data.states,
      title: "motor health at the slider's time, top view, nose up",
    });
    const slider = root.querySelector(".mmh-replay-slider");
    const clock = root.querySelector(".mmh-replay-time");
    const list = root.querySelector(".mmh-replay-motors");
    const span = Math.max(data.t_end_s - data.t_start_s, 1e-6);
    slider.min = "0";
    slider.max = "1000";
    slider.step = "1";
    const changeTimes = [];
    for (const key of Object.keys(data.timelines)) {
      for (const [t] of data.timelines[key]) {
        changeTimes.push(t);
      }
    }
    changeTimes.sort((a, b) => a - b);
    let current = data.t_start_s;

    function show(t) {
      current = Math.min(Math.max(t, data.t_start_s), data.t_end_s);
      slider.value = String(Math.round(((current - data.t_start_s) / span) * 1000));
      clock.textContent = `t = ${current.toFixed(1)} s`;
      root.dataset.time = current.toFixed(3);
      list.textContent = "";
      for (const m of [...data.layout].sort((a, b) => a.motor - b.motor)) {
        const changes = data.timelines[String(m.motor)] || [];
        const i = lastAtOrBefore(changes, current);
        const item = document.createElement("li");
        if (i < 0) {
          view.setMotor(m.motor, {state: "", kind: "waiting", note: "no data yet"});
          item.className = "kind-waiting";
          item.textContent = `M${m.motor}: no data yet`;
        } else {
          const [since, label] = changes[i];
          const info = data.states[label] || {};
          const kind = info.kind || "fault";
          const duration = global.MmhHexaView.formatDuration(current - since);
          const sinceText = label === "NORMAL" ? "" : "for " + duration;
          view.setMotor(m.motor, {state: label, kind: kind, description: info.description, since: sinceText});
          item.className = "kind-" + kind;
          item.textContent =
            `M${m.motor}: ${global.MmhHexaView.stateText(label)}` +
            (label === "NORMAL" ? "" : ` ${info.description || ""} since t = ${since.toFixed(1)} s (${duration})`);
        }
        item.dataset.motor = String(m.motor);
        list.appendChild(item);
      }
    }

    slider.addEventListener("input", () => show(data.t_start_s + (Number(slider.value) / 1000) * span));
    root.querySelector(".mmh-replay-prev").addEventListener("click", () => {
      const earlier = changeTimes.filter((t) => t < current - 1e-9);
      show(earlier.length ? earlier[earlier.length - 1] : data.t_start_s);
    });
    root.querySelector(".mmh-replay-next").addEventListener("click", () => {
      const later = changeTimes.find((t) => t > current + 1e-9);
      show(later === undefined ? data.t_end_s : later);
    });
    show(data.initial_t_s === null || data.initial_t_s === undefined ? data.t_start_s : data.initial_t_s);
    return {show: show};
  }

  global.MmhHexaReplay = {mount: mount, lastAtOrBefore: lastAtOrBefore};
})(window);
