// The report's workbench (designs.rs embeds the data): a sortable, filterable table of
// the drawn run's designs, a speed against cost of transport scatter with its Pareto
// front, hover figures on the maps, and a design card opened from any of them. Plain
// DOM code, no library: the page opens offline.
(function () {
  "use strict";
  const source = document.getElementById("design-data");
  if (!source) return;
  const data = JSON.parse(source.textContent);
  const byKey = new Map(data.designs.map((d) => [d.key, d]));
  let library = "feasible";
  let sortColumn = "fitness";
  let descending = true;

  const fixed = (v, n) => (v === null || v === undefined || !isFinite(v) ? "" : Number(v).toFixed(n));
  const percent = (v) => (v === null || v === undefined || !isFinite(v) ? "" : (100 * v).toFixed(1) + " %");
  function h(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    for (const c of children) e.append(c instanceof Node ? c : String(c));
    return e;
  }
  const svgNS = "http://www.w3.org/2000/svg";
  function s(tag, attrs) {
    const e = document.createElementNS(svgNS, tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    return e;
  }

  const columns = [
    { key: "cell", title: "cell", get: (d) => d.cell, text: (d) => String(d.cell) },
    { key: "legs", title: "legs", get: (d) => d.legs, text: (d) => String(d.legs) },
    { key: "legs_per_side", title: "legs per side", get: (d) => d.legs_per_side, text: (d) => String(d.legs_per_side) },
    { key: "mass", title: "mass kg (with payload)", get: (d) => d.mass, text: (d) => fixed(d.mass, 1) },
    { key: "speed", title: "speed m/s", get: (d) => d.stats && d.stats.speed, text: (d) => fixed(d.stats && d.stats.speed, 3) },
    { key: "cot", title: "cost of transport", get: (d) => d.stats && d.stats.cot, text: (d) => fixed(d.stats && d.stats.cot, 4) },
    { key: "fitness", title: "fitness", get: (d) => d.fitness, text: (d) => fixed(d.fitness, 4) },
    { key: "height", title: "height m", get: (d) => d.height, text: (d) => fixed(d.height, 2) },
    { key: "misses", title: "misses the brief", get: (d) => d.misses || "", text: (d) => d.misses || "" },
  ];

  function shown() {
    const legs = document.getElementById("filter-legs").value;
    const mass = parseFloat(document.getElementById("filter-mass").value);
    return data.designs.filter(
      (d) =>
        d.feasible === (library === "feasible") &&
        (legs === "" || d.legs_per_side === Number(legs)) &&
        (!isFinite(mass) || d.mass <= mass)
    );
  }

  function renderTable() {
    const table = document.getElementById("designs");
    const head = table.tHead;
    head.replaceChildren(
      h("tr", {}, ...columns
        .filter((c) => c.key !== "misses" || library === "infeasible")
        .filter((c) => c.key !== "fitness" || library === "feasible")
        .map((c) => {
          const th = h("th", { "data-sort": c.key, title: "sort by " + c.title }, c.title + (c.key === sortColumn ? (descending ? " ▼" : " ▲") : ""));
          return th;
        }))
    );
    const rows = shown();
    const col = columns.find((c) => c.key === sortColumn) || columns[0];
    rows.sort((a, b) => {
      const x = col.get(a), y = col.get(b);
      const missing = (v) => v === null || v === undefined || v === "";
      if (missing(x) !== missing(y)) return missing(x) ? 1 : -1;
      const c = typeof x === "string" ? x.localeCompare(y) : x - y;
      return descending ? -c : c;
    });
    const visible = columns
      .filter((c) => c.key !== "misses" || library === "infeasible")
      .filter((c) => c.key !== "fitness" || library === "feasible");
    table.tBodies[0].replaceChildren(
      ...rows.map((d) => h("tr", { "data-key": d.key }, ...visible.map((c) => h("td", {}, c.text(d)))))
    );
    document.getElementById("shown").textContent = rows.length + " of " + data.designs.filter((d) => d.feasible === (library === "feasible")).length + " designs shown";
    renderScatter(rows);
  }

  // Speed against cost of transport; the Pareto front (no other design both faster and
  // cheaper) joined by a line.
  function renderScatter(rows) {
    const box = document.getElementById("scatter");
    const points = rows.filter((d) => d.stats && isFinite(d.stats.speed) && isFinite(d.stats.cot));
    const W = 640, H = 360, L = 70, R = 20, T = 30, B = 50;
    const svg = s("svg", { width: W, height: H, viewBox: `0 0 ${W} ${H}`, role: "img" });
    const title = s("text", { x: L, y: 18, "font-size": 14 });
    title.textContent = "Speed against cost of transport (" + points.length + " designs; click a point for its card)";
    svg.append(title);
    if (points.length === 0) {
      box.replaceChildren(svg);
      return;
    }
    const xs = points.map((d) => d.stats.cot), ys = points.map((d) => d.stats.speed);
    let [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
    if (x1 === x0) { x0 -= 0.5; x1 += 0.5; }
    if (y1 === y0) { y0 -= 0.5; y1 += 0.5; }
    const px = (v) => L + ((v - x0) / (x1 - x0)) * (W - L - R);
    const py = (v) => H - B - ((v - y0) / (y1 - y0)) * (H - T - B);
    svg.append(s("rect", { x: L, y: T, width: W - L - R, height: H - T - B, fill: "none", stroke: "#999" }));
    for (const [v, t] of [[x0, 0], [x1, 1]]) {
      const lab = s("text", { x: px(v), y: H - B + 16, "font-size": 11, "text-anchor": t ? "end" : "start" });
      lab.textContent = v.toFixed(3);
      svg.append(lab);
    }
    for (const [v, t] of [[y0, 0], [y1, 1]]) {
      const lab = s("text", { x: L - 6, y: py(v) + (t ? 10 : 0), "font-size": 11, "text-anchor": "end" });
      lab.textContent = v.toFixed(2);
      svg.append(lab);
    }
    const xl = s("text", { x: L + (W - L - R) / 2, y: H - 12, "font-size": 12, "text-anchor": "middle" });
    xl.textContent = "cost of transport (energy / (mass g distance); lower is cheaper)";
    const yl = s("text", { x: 16, y: T + (H - T - B) / 2, "font-size": 12, "text-anchor": "middle", transform: `rotate(-90 16 ${T + (H - T - B) / 2})` });
    yl.textContent = "speed (m/s)";
    svg.append(xl, yl);
    const front = [];
    let cheapest = Infinity;
    for (const d of [...points].sort((a, b) => b.stats.speed - a.stats.speed || a.stats.cot - b.stats.cot)) {
      if (d.stats.cot < cheapest) {
        front.push(d);
        cheapest = d.stats.cot;
      }
    }
    const onFront = new Set(front.map((d) => d.key));
    svg.append(s("polyline", {
      points: front.map((d) => `${px(d.stats.cot).toFixed(1)},${py(d.stats.speed).toFixed(1)}`).join(" "),
      fill: "none", stroke: "#d62728", "stroke-width": 1.5, "pointer-events": "none",
    }));
    for (const d of points) {
      const dot = s("circle", {
        cx: px(d.stats.cot).toFixed(1), cy: py(d.stats.speed).toFixed(1), r: onFront.has(d.key) ? 5 : 3.5,
        fill: onFront.has(d.key) ? "#d62728" : "#1f77b4", "fill-opacity": 0.75, "data-key": d.key,
      });
      const tip = s("title");
      tip.textContent = "cell " + d.cell + ": " + fixed(d.stats.speed, 3) + " m/s, cost of transport " + fixed(d.stats.cot, 3) + ", " + fixed(d.mass, 1) + " kg with payload";
      dot.append(tip);
      svg.append(dot);
    }
    const note = s("text", { x: W - R, y: T + 14, "font-size": 11, "text-anchor": "end", fill: "#d62728" });
    note.textContent = "red: the Pareto front (" + front.length + ")";
    svg.append(note);
    box.replaceChildren(svg);
  }

  function figures(d) {
    const st = d.stats || {};
    const rows = [
      ["library", d.feasible ? "feasible (meets the brief)" : "infeasible: " + (d.misses || "misses the brief")],
      ["fitness (1 / cost of transport)", fixed(d.fitness, 4), "fitness"],
      ["speed (m/s)", fixed(st.speed, 3), "speed"],
      ["cost of transport", fixed(st.cot, 4), "cot"],
      ["distance walked (m)", fixed(st.distance, 3), "distance"],
      ["energy spent (J)", fixed(st.energy, 1), "energy"],
      ["trial length (s)", fixed(st.duration, 2), "duration"],
      ["mass with the " + data.payload + " kg payload (kg)", fixed(d.mass, 2), "mass"],
      ["mass without payload (kg)", fixed(d.mass_without_payload, 2), "mass_without_payload"],
      ["height at the start pose (m)", fixed(d.height, 2), "height"],
      ["legs (per side)", d.legs + " (" + d.legs_per_side + ")", "legs"],
      ["stays up after the trial", d.feasible ? "checked for " + data.stays_up_seconds + " s" : ""],
      ["largest torque on any joint, of its limit (100 % = held at the limit)", percent(st.peak_torque_ratio), "peak_torque_ratio"],
      ["foot slip on the ground (m, mean per foot)", fixed(st.foot_slip, 3), "foot_slip"],
      ["share of the feet's forward travel made within the ground clearance (skating)", percent(st.low_forward_share), "low_forward_share"],
      ["duty factor (share of time a foot is down)", percent(st.duty_factor), "duty_factor"],
    ];
    const blank = d.stats ? "" : "— (no trial figures: it " + (d.misses || "ended early") + ")";
    return h("table", { class: "figures" }, ...rows.map(([k, v, f]) => h("tr", {}, h("th", {}, k), h("td", f ? { "data-field": f } : {}, v === "" && f && f !== "fitness" ? blank : v))));
  }

  function featureTable(d) {
    return h("table", { class: "features" },
      h("tr", {}, h("th", {}, "feature"), h("th", {}, "value"), h("th", {}, "bin")),
      ...data.feature_names.map((name, i) => h("tr", {},
        h("td", {}, "d" + (i + 1) + " " + name + (data.feature_units[i] ? " (" + data.feature_units[i] + (name === "total_mass" ? ", with payload" : "") + ")" : "")),
        h("td", {}, data.whole[i] ? String(Math.round(d.features[i])) : fixed(d.features[i], 3)),
        h("td", {}, String(d.bins[i])))));
  }

  function motorTable(d) {
    if (!d.motors) return h("p", {}, "No motor sizing: the report was made without replaying this design's trial.");
    const head = ["joint", "peak torque Nm", "RMS torque Nm", "torque limit Nm", "peak / limit", "peak speed rad/s", "max_speed gene rad/s", "peak power W", "RMS power W"];
    return h("table", { class: "motors" },
      h("tr", {}, ...head.map((t) => h("th", {}, t))),
      ...d.motors.map((m) => h("tr", {},
        h("td", {}, m.joint), h("td", {}, fixed(m.peak_torque, 1)), h("td", {}, fixed(m.rms_torque, 1)),
        h("td", {}, fixed(m.torque_limit, 1)), h("td", {}, percent(m.torque_limit > 0 ? m.peak_torque / m.torque_limit : NaN)),
        h("td", {}, fixed(m.peak_speed, 2)), h("td", {}, fixed(m.speed_limit, 2)),
        h("td", {}, fixed(m.peak_power, 1)), h("td", {}, fixed(m.rms_power, 1)))),
      h("caption", {}, "Torque limits are the genome's motor*_max_torque times its strength multiplier; the simulation never passes them. The max_speed gene sets the gait's amplitude (the sweep a joint is asked for per cycle); it is not a speed limit the simulation holds, so a joint's peak speed may pass it: size a motor's speed from the peak speed column. Motor 0 is at the hip, 2 at the foot end; in brackets, the joint's name in the URDF."));
  }

  function openCard(d) {
    if (!d) return;
    const card = document.getElementById("card");
    const f = d.files;
    const downloads = h("p", { class: "downloads" }, "Download: ",
      h("a", { href: f.genome, download: "", target: "_blank", "data-download": "genome" }, "genome file"), " · ",
      h("a", { href: f.urdf, download: "", target: "_blank", "data-download": "urdf" }, "URDF"), " + ",
      h("a", { href: f.pose, download: "", target: "_blank", "data-download": "pose" }, "start pose"));
    const pictures = h("div", { class: "pictures" }, h("img", { src: f.drawing, alt: "side, front and top views" }));
    if (f.replay) pictures.append(h("div", { class: "replay" }, h("img", { src: f.replay, alt: "animated replay of the trial" })));
    else pictures.append(h("p", {}, "No animated replay of this design in the report (report --replays N makes them for the N fittest designs and the N nearest near misses). From the report's folder, ",
      h("code", {}, "strider-worker eval " + f.genome + " --scheme genome --experiment designs/experiment.toml --replay replay.svg"),
      " replays its trial exactly."));
    card.replaceChildren(
      h("button", { class: "close", title: "close" }, "×"),
      h("h3", { "data-key": d.key }, "Run " + data.run + ", cell " + d.cell + (d.feasible ? "" : " (near miss)")),
      h("p", { class: "brief" }, "The brief: " + data.brief + "."),
      downloads, pictures, figures(d),
      h("h4", {}, "Motor sizing (over the trial, every physics step)"), motorTable(d),
      h("h4", {}, "Features"), featureTable(d),
      h("h4", {}, "Genome"), h("pre", {}, JSON.stringify(d.genome, null, 2)));
    card.hidden = false;
    card.scrollTop = 0;
    // The address names the open card, to copy or bookmark.
    history.replaceState(null, "", "#design=" + d.key);
  }

  function closeCard() {
    document.getElementById("card").hidden = true;
    history.replaceState(null, "", window.location.pathname + window.location.search);
  }

  function designAt(cell) {
    const mine = (library === "feasible" ? "f" : "i") + cell;
    const other = (library === "feasible" ? "i" : "f") + cell;
    return byKey.get(mine) || byKey.get(other);
  }

  // A pair map's block names its bins in a <title> (for the SVG file alone); on the page
  // the tooltip says it, beside the design's figures.
  for (const t of document.querySelectorAll("figure rect[data-cell] > title")) {
    t.parentNode.dataset.bins = t.textContent;
    t.remove();
  }
  const tip = document.getElementById("tooltip");
  document.addEventListener("mouseover", (ev) => {
    const t = ev.target.closest && ev.target.closest("[data-cell]");
    const d = t && designAt(Number(t.dataset.cell));
    if (!d) { tip.hidden = true; return; }
    const st = d.stats || {};
    tip.textContent = (t.dataset.bins ? t.dataset.bins + ": best " : "") + "cell " + d.cell + (d.feasible ? "" : " (near miss: " + (d.misses || "") + ")") +
      " · fitness " + (fixed(d.fitness, 4) || "none") + (d.stats ? " · " + fixed(st.speed, 2) + " m/s · COT " + fixed(st.cot, 3) : "") +
      " · " + fixed(d.mass, 1) + " kg with payload · " + d.legs + " legs";
    tip.style.left = ev.pageX + 12 + "px";
    tip.style.top = ev.pageY + 12 + "px";
    tip.hidden = false;
  });
  document.addEventListener("click", (ev) => {
    if (!ev.target.closest) return;
    if (ev.target.closest("#card .close")) { closeCard(); return; }
    const sort = ev.target.closest("th[data-sort]");
    if (sort) {
      if (sortColumn === sort.dataset.sort) descending = !descending;
      else { sortColumn = sort.dataset.sort; descending = true; }
      renderTable();
      return;
    }
    const k = ev.target.closest("[data-key]");
    if (k && !ev.target.closest("#card")) { openCard(byKey.get(k.dataset.key)); return; }
    const c = ev.target.closest("[data-cell]");
    if (c) openCard(designAt(Number(c.dataset.cell)));
  });
  document.addEventListener("keydown", (ev) => {
    if (ev.key === "Escape") closeCard();
  });
  for (const radio of document.querySelectorAll("input[name=library]")) {
    radio.addEventListener("change", () => {
      library = radio.value;
      if (library === "infeasible" && sortColumn === "fitness") sortColumn = "speed";
      if (library === "feasible" && sortColumn === "misses") { sortColumn = "fitness"; descending = true; }
      renderTable();
    });
  }
  const legs = document.getElementById("filter-legs");
  for (const n of [...new Set(data.designs.map((d) => d.legs_per_side))].sort((a, b) => a - b)) {
    legs.append(h("option", { value: n }, n));
  }
  legs.addEventListener("change", renderTable);
  document.getElementById("filter-mass").addEventListener("input", renderTable);
  renderTable();
  // A link to a design: report.html#design=f123 (feasible, cell 123) or #design=i123.
  const follow = () => {
    const linked = /^#design=([fi]\d+)$/.exec(window.location.hash);
    if (linked) openCard(byKey.get(linked[1]));
  };
  window.addEventListener("hashchange", follow);
  follow();
})();
