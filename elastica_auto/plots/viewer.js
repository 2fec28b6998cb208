// elastica-auto view: the page's own script. Plotly draws, zooms, pans, toggles branches from
// the legend and finds the point under the mouse; this script only (1) builds the traces of
// the chosen panel and columns from the file's data (#data, see viewer.py: page_data), styled
// as `elastica-auto plot` draws them, and (2) shows the hovered or pinned point beside the
// diagram: its values, its configuration and the label to restart from.
"use strict";
(function () {
  const D = JSON.parse(document.getElementById("data").textContent);
  const $ = (id) => document.getElementById(id);
  const gd = $("plot");
  const branch = Object.fromEntries(D.branches.map((b) => [b.number, b]));
  const state = {panel: 0, x: D.x, y: D.y, fold: D.fold, snaps: false, pinned: null};
  const fmt = (v) => (v === null ? "nan" : Number(v.toPrecision(7)).toString());

  function options(select, names, chosen) {
    for (const [value, text] of names) select.add(new Option(text, value, false, value === chosen));
  }
  options($("panel"), D.panels.map((p, k) => [String(k), p.title]), "0");
  options($("x"), D.columns.map((q) => [q, q]), D.x);
  options($("y"), D.columns.map((q) => [q, q]), D.y);
  $("fold").checked = D.fold;

  const period = () => (state.fold ? D.periods[state.x] : undefined);
  // x of branch b, folded into [0, period) when asked (and x is periodic)
  function xs(b) {
    const p = period(), x = b.columns[state.x];
    return p ? x.map((v) => (v === null ? null : ((v % p) + p) % p)) : x;
  }

  // The index that styles the line at each point of branch b, as diagram.line_index gives
  // it: its own, but at a fold or branch point the next point's (the style changes at the
  // point itself, where its marker is, not one segment later). D.turns: the marks' kinds
  // there (viewer.py: core.labels.TURNS and the unlocated fold's mark).
  function lineIndex(b) {
    const turns = new Set(D.turns.flatMap((kind) => b.marks[kind] || []));
    return b.index.map((k, i) => (turns.has(i) && i + 1 < b.index.length ? b.index[i + 1] : k));
  }

  // The traces of branch b: its legend entry (no points), a line per run of equal stability
  // index (neighbouring runs share the point where the index changes), broken where a folded
  // x wraps around, as diagram.index_runs splits them, then a marker trace per kind of
  // labelled point. All in the branch's legend group: its legend entry hides the branch.
  function traces(b) {
    const x = xs(b), y = b.columns[state.y], p = period(), index = lineIndex(b);
    const out = [{type: "scatter", mode: "lines", x: [null], y: [null], name: b.name,
                  legendgroup: String(b.number), line: {color: "#555", width: 2},
                  hoverinfo: "skip", meta: {branch: b.number, kind: "legend"}}];
    const common = (rows) => ({
      x: rows.map((i) => x[i]), y: rows.map((i) => y[i]), customdata: rows,
      text: rows.map((i) => `${b.name} pt ${i + 1}` + (b.labels[i] ? ` ${b.labels[i]}` : "")),
      hovertemplate: "%{text}<extra></extra>", legendgroup: String(b.number), name: b.name,
    });
    let start = 0;
    for (let i = 0; i < x.length; i++) {
      const last = i === x.length - 1;
      const wrap = !last && p !== undefined && Math.abs(x[i + 1] - x[i]) > p / 2;
      if (!last && !wrap && index[i + 1] === index[i]) continue;
      const stop = last || wrap ? i + 1 : i + 2;
      const s = D.styles[index[start]];
      const rows = Array.from({length: stop - start}, (_, k) => start + k);
      // every point drawn: Plotly would otherwise drop points of nearly straight stretches
      out.push({...common(rows), type: "scatter", mode: "lines", showlegend: false,
                line: {color: s.color, dash: s.dash, width: s.width, simplify: false},
                meta: {branch: b.number, kind: "line"}});
      start = i + 1;
    }
    for (const [kind, rows] of Object.entries(b.marks)) {
      const m = D.markers[kind];
      out.push({...common(rows), type: "scatter", mode: "markers", showlegend: false,
                marker: {symbol: m.symbol, color: m.color, size: m.size, line: m.line},
                meta: {branch: b.number, kind: kind}});
    }
    return out;
  }

  // Snap-back arrows: from each fold of the panel to its targets (same parameters; the
  // target's ordinates), when asked for.
  function arrows(numbers) {
    if (!state.snaps) return [];
    const p = period(), at = (v) => (p ? ((v % p) + p) % p : v);
    return D.snaps.filter((s) => numbers.includes(s.branch)).map((s) => {
      const [br, pt] = D.labels[s.lp], b = branch[br], i = pt - 1;
      const to = (q) => (q in s.target ? s.target[q] : b.columns[q][i]);
      return {x: at(to(state.x)), y: to(state.y), ax: at(b.columns[state.x][i]),
              ay: b.columns[state.y][i], xref: "x", yref: "y", axref: "x", ayref: "y",
              showarrow: true, arrowhead: 2, arrowwidth: 1.2, arrowcolor: D.snap_color,
              text: ""};
    });
  }

  function draw() {
    const numbers = D.panels[state.panel].branches;
    const data = numbers.flatMap((n) => traces(branch[n]));
    const p = period();
    Plotly.react(gd, data, {
      // a new panel or new columns: zoom out; the same: keep the user's zoom and legend
      uirevision: [state.panel, state.x, state.y, state.fold].join("|"),
      margin: {l: 60, r: 10, t: 30, b: 45}, hovermode: "closest", hoverdistance: 15,
      title: {text: D.panels[state.panel].title, font: {size: 14}},
      xaxis: {title: {text: state.x}, range: p ? [0, p] : undefined, autorange: !p,
              zeroline: false, showline: true, mirror: true, ticks: "inside"},
      yaxis: {title: {text: state.y}, zeroline: false, showline: true, mirror: true,
              ticks: "inside"},
      legend: {title: {text: "branches"}, groupclick: "togglegroup"},
      annotations: arrows(numbers), plot_bgcolor: "white",
    }, {displaylogo: false, responsive: true, scrollZoom: true});
  }

  // The side panel: point i of branch b. Its configuration is its own if it is labelled,
  // else the nearest labelled point's (the file stores solutions of labelled points only).
  function show(b, i) {
    const label = b.labels[i], near = label ? i : b.near[i];
    const stored = near >= 0 ? b.labels[near] : "";
    const img = $("config");
    img.src = D.images[stored] || "";
    img.dataset.label = stored;
    $("caption").textContent = !D.images[stored]
      ? `no configuration: ${!stored ? "no labelled point on this branch"
                             : D.missing[stored] || D.no_images || "not drawn"}`
      : label ? `${label}: its configuration`
      : `nearest stored configuration: ${stored} (point ${near + 1}; this is point ${i + 1})`;
    $("restart").value = stored ? `--from ${D.file}:${stored}` : "";
    const k = b.index[i];
    const rows = [["branch", b.name], ["point", String(i + 1)], ["label", label || "-"],
                  ...D.parameters.map((q) => [q, fmt(b.columns[q][i])]),
                  ...D.ordinates.map((q) => [q, fmt(b.columns[q][i])]),
                  ["index", k >= 0 ? String(k) : "unknown"],
                  ["transition", b.transitions[i] || "-"]];
    $("info").replaceChildren(...rows.map(([name, value]) => {
      const tr = document.createElement("tr");
      for (const text of [name, value]) tr.insertCell().textContent = text;
      return tr;
    }));
  }

  const pointOf = (ev) => ev.points[0] && [branch[ev.points[0].data.meta.branch],
                                           ev.points[0].customdata];
  function pin(at) {
    state.pinned = at;
    $("pinned").textContent = at ? `pinned: ${at[0].name} pt ${at[1] + 1}` : "";
    $("unpin").hidden = !at;
    if (at) show(...at);
  }

  draw();
  // Plotly's responsive option follows the window's size only: the diagram keeps its width
  // when its box narrows without the window changing (a vertical scroll bar appearing as
  // the side panel fills, say), and would then cover the side panel's left edge
  new ResizeObserver(() => Plotly.Plots.resize(gd)).observe(gd);
  // at first, the panel's first labelled point
  const first = branch[D.panels[0].branches[0]];
  show(first, Math.max(0, first.labels.findIndex((name) => name)));
  gd.on("plotly_hover", (ev) => { const at = pointOf(ev); if (at && !state.pinned) show(...at); });
  gd.on("plotly_click", (ev) => pin(pointOf(ev)));
  $("unpin").onclick = () => pin(null);
  $("copy").onclick = () => {
    $("restart").select();      // selected: where both ways of copying are refused, Ctrl-C
    navigator.clipboard?.writeText($("restart").value).catch(() => document.execCommand("copy"));
  };
  for (const id of ["panel", "x", "y", "fold", "snaps"]) {
    $(id).onchange = (ev) => {
      const t = ev.target;
      state[id] = t.type === "checkbox" ? t.checked : id === "panel" ? Number(t.value) : t.value;
      if (id === "x") $("fold").disabled = !(state.x in D.periods);
      draw();
    };
  }
  $("fold").disabled = !(state.x in D.periods);

  // the key to the line styles and the markers
  const key = Object.values(D.styles).map((s) => [s.label,
    `<line x1="0" y1="6" x2="36" y2="6" stroke="${s.color}" stroke-width="${s.width}"
       stroke-dasharray="${s.dash === "solid" ? "" : s.dash.replace(/px/g, "")}"/>`]);
  const kinds = new Set(D.branches.flatMap((b) => Object.keys(b.marks)));
  const shapes = {circle: '<circle cx="18" cy="6" r="4"/>', square: '<rect x="14" y="2" ' +
    'width="8" height="8"/>', diamond: '<path d="M18 1L23 6L18 11L13 6Z"/>'};
  for (const [kind, m] of Object.entries(D.markers)) {
    if (kinds.has(kind)) key.push([m.text, `<g fill="${m.color}" stroke="${m.line.color}">${
      shapes[m.symbol] || '<path d="M14 2L22 10M14 10L22 2" stroke-width="1.5"/>'}</g>`]);
  }
  $("key").innerHTML = key.map(([text, svg]) =>
    `<span><svg width="36" height="12">${svg}</svg> ${text}</span>`).join("");
}());
