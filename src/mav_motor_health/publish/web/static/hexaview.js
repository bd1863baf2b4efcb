/* Top view of a multicopter with each motor coloured by its announced state.
 *
 * Shared by the live display (display.js) and the replay report (inlined by hexaview.py), so both show
 * the same picture. No dependencies; defines window.MmhHexaView once.
 *
 *   const view = MmhHexaView.create(containerElement, {layout, states});
 *   view.setMotor(4, {state: "F3.1", description: "propeller damage", since: "for 12 s"});
 *   view.setMotor(2, {state: "NO_DATA", note: "silent 14 s"});
 *   view.setNoData("vehicle offline");   // or null to clear
 *
 * layout: [{motor, angle_deg, spin: "CW"|"CCW"}], angle from the nose, positive to the right.
 * states: {label: {kind: "ok"|"fault"|"sensor"|"nodata", description}}.
 */
(function (global) {
  "use strict";
  if (global.MmhHexaView) {
    return;
  }
  const SVGNS = "http://www.w3.org/2000/svg";
  const ARM_RADIUS = 150;
  const DISC_RADIUS = 58;
  let instances = 0;

  function el(name, attrs, parent) {
    const node = document.createElementNS(SVGNS, name);
    for (const key of Object.keys(attrs || {})) {
      node.setAttribute(key, String(attrs[key]));
    }
    if (parent) {
      parent.appendChild(node);
    }
    return node;
  }

  function text(parent, x, y, cls, content) {
    const node = el("text", {x: x, y: y, class: cls, "text-anchor": "middle"}, parent);
    node.textContent = content;
    return node;
  }

  /* Screen point at bearing phi (degrees from up, clockwise) and radius rho around (cx, cy). */
  function polar(cx, cy, rho, phiDeg) {
    const a = (phiDeg * Math.PI) / 180;
    return [cx + rho * Math.sin(a), cy - rho * Math.cos(a)];
  }

  function kindOf(states, label) {
    if (!label) {
      return "waiting";
    }
    const info = states && states[label];
    if (info && info.kind) {
      return info.kind;
    }
    return "fault"; // a label this page does not know: show it, and treat it as a fault
  }

  function stateText(label) {
    if (!label) {
      return "—";
    }
    if (label === "NORMAL") {
      return "OK";
    }
    if (label === "NO_DATA") {
      return "NO DATA";
    }
    if (label === "SENSOR_FAULT") {
      return "SENSOR";
    }
    return label;
  }

  function create(container, options) {
    const opts = options || {};
    const layout = opts.layout || [];
    const states = opts.states || {};
    const uid = "mmh-hv-" + ++instances;
    const svg = el("svg", {
      class: "mmh-hv",
      viewBox: "-235 -240 470 482",
      role: "img",
      "aria-label": opts.title || "motor health, top view, nose up",
    });
    const defs = el("defs", {}, svg);
    const marker = el(
      "marker",
      {id: uid + "-arrow", viewBox: "0 0 10 10", refX: 5, refY: 5, markerWidth: 5, markerHeight: 5, orient: "auto-start-reverse"},
      defs,
    );
    el("path", {d: "M0,0 L10,5 L0,10 z", class: "mmh-hv-arrowhead"}, marker);

    // A motor on the nose (plus frames) takes the top centre: the FRONT mark then goes to the corner.
    const noseMotor = layout.some((m) => Math.abs(m.angle_deg) < 20);
    const front = text(svg, noseMotor ? -228 : 0, -210, "mmh-hv-front", "▲ FRONT");
    if (noseMotor) {
      front.setAttribute("text-anchor", "start");
    }
    const arms = el("g", {class: "mmh-hv-arms"}, svg);
    const motorsGroup = el("g", {class: "mmh-hv-motors"}, svg);
    const motors = {};
    for (const m of layout) {
      const [x, y] = polar(0, 0, ARM_RADIUS, m.angle_deg);
      el("line", {x1: 0, y1: 0, x2: x, y2: y, class: "mmh-hv-arm"}, arms);
      const g = el("g", {class: "mmh-hv-motor kind-waiting", "data-motor": m.motor, "data-state": "", "data-kind": "waiting"}, motorsGroup);
      const title = el("title", {}, g);
      el("circle", {cx: x, cy: y, r: DISC_RADIUS, class: "mmh-hv-disc"}, g);
      // Spin arrow on the outer side of the disc, turning as the propeller does seen from above.
      const from = m.spin === "CW" ? m.angle_deg - 55 : m.angle_deg + 55;
      const to = m.spin === "CW" ? m.angle_deg + 55 : m.angle_deg - 55;
      const rho = DISC_RADIUS + 9;
      const p0 = polar(x, y, rho, from);
      const p1 = polar(x, y, rho, to);
      el(
        "path",
        {
          d: `M${p0[0].toFixed(1)},${p0[1].toFixed(1)} A${rho},${rho} 0 0 ${m.spin === "CW" ? 1 : 0} ${p1[0].toFixed(1)},${p1[1].toFixed(1)}`,
          class: "mmh-hv-spin",
          "marker-end": `url(#${uid}-arrow)`,
          "data-spin": m.spin,
        },
        g,
      );
      text(g, x, y - 6, "mmh-hv-number", String(m.motor));
      const label = text(g, x, y + 24, "mmh-hv-state", "—");
      // Under the disc, unless the arm runs there (a motor near the nose): then above it.
      const sinceY = Math.abs(m.angle_deg) < 20 ? y - DISC_RADIUS - 16 : y + DISC_RADIUS + (Math.abs(m.angle_deg) > 95 ? 30 : 26);
      const since = text(g, x, sinceY, "mmh-hv-since", "");
      motors[m.motor] = {group: g, label: label, since: since, title: title, spin: m.spin};
    }
    // The body: a plate with an arrow to the nose.
    el("circle", {cx: 0, cy: 0, r: 40, class: "mmh-hv-body"}, svg);
    el("path", {d: "M0,-30 L16,8 L0,0 L-16,8 z", class: "mmh-hv-nose"}, svg);

    const overlay = el("g", {class: "mmh-hv-overlay", visibility: "hidden"}, svg);
    el("rect", {x: -235, y: -240, width: 470, height: 482, class: "mmh-hv-overlay-bg"}, overlay);
    el("rect", {x: -190, y: -62, width: 380, height: 106, rx: 14, class: "mmh-hv-overlay-box"}, overlay);
    text(overlay, 0, -8, "mmh-hv-overlay-title", "NO DATA");
    const overlayReason = text(overlay, 0, 24, "mmh-hv-overlay-reason", "");

    container.appendChild(svg);

    return {
      svg: svg,
      /* state: announced label or "" (nothing yet); description, since, note: free text. */
      setMotor(number, info) {
        const m = motors[number];
        if (!m) {
          return;
        }
        const label = info && info.state ? info.state : "";
        const kind = info && info.kind ? info.kind : kindOf(states, label);
        m.group.setAttribute("class", "mmh-hv-motor kind-" + kind);
        m.group.setAttribute("data-state", label);
        m.group.setAttribute("data-kind", kind);
        m.label.textContent = kind === "nodata" && label !== "NO_DATA" ? "NO DATA" : stateText(label);
        const sub = (info && (info.note || info.since)) || "";
        m.since.textContent = sub;
        const desc = (info && info.description) || (states[label] && states[label].description) || "";
        m.title.textContent = `motor ${number} (${m.spin}): ${label || "no state yet"}${desc ? " — " + desc : ""}${sub ? ", " + sub : ""}`;
      },
      setNoData(reason) {
        if (reason) {
          svg.classList.add("vehicle-nodata");
          overlay.setAttribute("visibility", "visible");
          overlayReason.textContent = reason;
        } else {
          svg.classList.remove("vehicle-nodata");
          overlay.setAttribute("visibility", "hidden");
          overlayReason.textContent = "";
        }
      },
      kindOf(label) {
        return kindOf(states, label);
      },
    };
  }

  /* "12 s", "3 min 05 s", "2 h 04 min" */
  function formatDuration(seconds) {
    if (!isFinite(seconds)) {
      return "";
    }
    const s = Math.max(0, Math.floor(seconds));
    if (s < 60) {
      return s + " s";
    }
    if (s < 3600) {
      return Math.floor(s / 60) + " min " + String(s % 60).padStart(2, "0") + " s";
    }
    return Math.floor(s / 3600) + " h " + String(Math.floor((s % 3600) / 60)).padStart(2, "0") + " min";
  }

  global.MmhHexaView = {create: create, formatDuration: formatDuration, stateText: stateText};
})(window);
