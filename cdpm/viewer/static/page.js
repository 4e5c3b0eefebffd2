// The inspection page of `cdpm view` (cdpm/viewer/page.py serves it).
//
// Every URL is relative: page, scene (the iframe's scene/) and the scene's
// websocket share the page's origin, whichever loopback name or forwarded
// port reached it.
//
// Loads the model (api/model), builds one slider per natural coordinate,
// the named-pose picker, the legend and the map toggle, and renders the
// panel. A slider move sends the pose to api/pose; while a request is in
// flight, further moves are coalesced into the next request, so the panel
// follows the slider without a queue of stale poses.
//
// Input-to-panel time: from the slider's input event (the oldest one a
// request carries) to the end of the panel's DOM update, with
// performance.now(). The last one is shown ("updated in X ms") and kept in
// #update-time's data-ms; every one is in window.cdpm.timings [ms].
"use strict";

let inFlight = false; // a pose request is on its way
let pending = null; // {body, t0}: the next request, t0 of its oldest input event

// timings: input-to-panel times [ms]; server: each panel's server-side
// seconds ({analysis, draw}); busy(): a request is in flight or waiting
const cdpm = { timings: [], server: [], natural: [], model: null };
cdpm.busy = () => inFlight || pending !== null;
window.cdpm = cdpm;

const $ = (id) => document.getElementById(id);

// the page's token, written into it by the server: a POST without it is refused
const token = document.querySelector('meta[name="cdpm-token"]').content;

function el(tag, attrs = {}, children = []) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (key === "text") node.textContent = value;
    else if (key === "style") node.style.cssText = value;
    else node.setAttribute(key, value);
  }
  for (const child of children) node.append(child);
  return node;
}

function fmt(value, digits = 4) {
  if (value === null || value === undefined) return "-";
  const text = Number(value).toFixed(digits);
  return /^-0\.?0*$/.test(text) ? text.slice(1) : text;
}

// light colours (amber, grey) get dark text on their badge
function isLight(hex) {
  const n = parseInt(hex.slice(1), 16);
  const [r, g, b] = [(n >> 16) & 255, (n >> 8) & 255, n & 255];
  return 0.299 * r + 0.587 * g + 0.114 * b > 160;
}

function badge(text, color) {
  return el("span", { class: isLight(color) ? "badge light" : "badge", style: `background:${color}`, text });
}

// ------------------------------------------------------------------ requests

async function post(path, body) {
  const response = await fetch(path, {
    method: "POST",
    headers: { "Content-Type": "application/json", "X-Cdpm-Token": token },
    body: JSON.stringify(body),
  });
  const content = await response.json();
  if (!response.ok) throw new Error(content.error || response.statusText);
  return content;
}

function requestPose(body, t0) {
  pending = { body, t0: pending ? pending.t0 : t0 };
  if (!inFlight) flush();
}

async function flush() {
  const job = pending;
  pending = null;
  inFlight = true;
  try {
    const panel = await post("api/pose", job.body);
    render(panel);
    const ms = performance.now() - job.t0;
    cdpm.timings.push(ms);
    cdpm.server.push(panel.seconds);
    const time = $("update-time");
    time.dataset.ms = ms.toFixed(2);
    const s = panel.seconds || {};
    time.textContent =
      `updated in ${ms.toFixed(1)} ms (analysis ${(1e3 * (s.analysis || 0)).toFixed(1)} ms, ` +
      `scene ${(1e3 * (s.draw || 0)).toFixed(1)} ms)`;
    time.classList.remove("error");
  } catch (error) {
    $("update-time").textContent = `update failed: ${error.message}`;
    $("update-time").classList.add("error");
  } finally {
    inFlight = false;
    if (pending) flush();
  }
}

// ------------------------------------------------------------------ building

function buildSliders(coordinates) {
  const box = $("sliders");
  let group = null;
  coordinates.forEach((c, i) => {
    // a multi-coordinate joint's coordinates (e.g. a free flyer's x ... yaw)
    // under the joint's name, each labelled by its own part
    const dot = c.name.lastIndexOf(".");
    const joint = dot > 0 ? c.name.slice(0, dot) : null;
    if (joint !== group && joint !== null) box.append(el("div", { class: "slider-group", text: joint }));
    group = joint;
    const label = joint === null ? c.name : c.name.slice(dot + 1);
    const id = `slider-${i}`;
    const range = el("input", {
      type: "range", id, min: c.low, max: c.high, step: c.step, "data-name": c.name,
      "aria-label": `${c.name} [${c.unit}]`,
    });
    const number = el("input", {
      type: "number", id: `value-${i}`, step: "any", "aria-label": `${c.name} value [${c.unit}]`,
    });
    range.addEventListener("input", () => {
      const t0 = performance.now();
      cdpm.natural[i] = Number(range.value);
      number.value = fmt(cdpm.natural[i]);
      setActivePose(null);
      requestPose({ natural: cdpm.natural.slice() }, t0);
    });
    number.addEventListener("change", () => {
      const t0 = performance.now();
      const value = Number(number.value);
      if (number.value.trim() === "" || !Number.isFinite(value)) {
        number.value = fmt(cdpm.natural[i]); // an empty or bad entry keeps the pose
        return;
      }
      cdpm.natural[i] = value;
      range.value = value;
      setActivePose(null);
      requestPose({ natural: cdpm.natural.slice() }, t0);
    });
    box.append(el("div", { class: "slider-row" }, [
      el("label", { for: id, text: label, title: c.name }), range, number,
      el("span", { class: "unit", text: c.unit }),
    ]));
  });
}

function buildPoses(poses) {
  const picker = $("pose-picker");
  if (!poses.length) {
    picker.append(el("span", { class: "muted", text: "the spec names no poses" }));
  }
  for (const pose of poses) {
    const button = el("button", { type: "button", "data-pose": pose.name, "aria-pressed": "false", text: pose.name });
    button.addEventListener("click", () => {
      setActivePose(pose.name);
      requestPose({ pose: pose.name }, performance.now());
    });
    picker.append(button);
  }
}

function setActivePose(name) {
  for (const button of $("pose-picker").querySelectorAll("button")) {
    button.setAttribute("aria-pressed", String(button.dataset.pose === name));
  }
}

function buildLegend(legend) {
  const verdicts = $("legend-verdicts");
  for (const v of legend.verdicts) {
    verdicts.append(el("span", { class: "item" }, [el("span", { class: "swatch", style: `background:${v.color}` }), ` ${v.label}`]));
  }
  legendList($("legend-cables"), legend.cables);
  $("legend-outputs-title").hidden = !legend.outputs.length;
  legendList($("legend-outputs"), legend.outputs);
}

// items {label, meaning, color?, to?}: a swatch (a ramp from color to to) when coloured
function legendList(box, items) {
  for (const c of items) {
    const fill = c.to ? `linear-gradient(90deg, ${c.color}, ${c.to})` : c.color;
    const swatch = c.color ? [el("span", { class: "swatch", style: `background:${fill}` }), " "] : [];
    box.append(el("div", { class: "item", "data-legend": c.label }, [
      ...swatch,
      el("span", { class: "label", text: c.label }), " ",
      el("span", { class: "meaning", text: c.meaning }),
    ]));
  }
}

function buildMap(map) {
  if (!map) return;
  $("map-section").hidden = false;
  const toggle = $("map-toggle");
  toggle.checked = map.visible;
  $("map-label").textContent = `show ${map.name || "the map"} (${map.points} poses, coloured by ${map.color_by})`;
  toggle.addEventListener("change", async () => {
    try {
      const state = await post("api/map", { visible: toggle.checked });
      toggle.checked = state.visible;
    } catch (error) {
      $("map-label").textContent = `map: ${error.message}`;
    }
  });
}

function buildCopy() {
  $("copy-q").addEventListener("click", async () => {
    const text = $("q-text").textContent;
    let copied = false;
    try {
      await navigator.clipboard.writeText(text);
      copied = true;
    } catch (error) {
      // clipboard API refused (e.g. no permission): select and copy the text
      const range = document.createRange();
      range.selectNodeContents($("q-text"));
      const selection = window.getSelection();
      selection.removeAllRanges();
      selection.addRange(range);
      copied = document.execCommand("copy");
    }
    $("copy-note").textContent = copied ? "copied" : "select the text to copy it";
  });
}

// ------------------------------------------------------------------ rendering

// a number as Python's format(x, ".{digits}g") writes it (the text report's numbers)
function fmtG(x, digits) {
  const value = Number(x);
  if (value === 0 || !Number.isFinite(value)) return String(value);
  const trim = (text) => (text.includes(".") ? text.replace(/\.?0+$/, "") : text);
  const [mantissa, power] = value.toExponential(digits - 1).split("e");
  const exponent = Number(power);
  if (exponent < -4 || exponent >= digits) {
    const sign = exponent < 0 ? "-" : "+";
    return `${trim(mantissa)}e${sign}${String(Math.abs(exponent)).padStart(2, "0")}`;
  }
  return trim(value.toFixed(digits - 1 - exponent));
}

// r_T is a lower bound: the true margin lies in [value, value + error]; the
// words are the text report's (cdpm/text/report.py): "(exact)" or
// "(a lower bound: at most E more)"
function reachText(reach) {
  if (!reach) return "unavailable";
  const horizon = `within T = ${fmtG(reach.horizon, 3)} s`;
  // JSON null: NaN (not computed) or infinite (a mode grows too fast within T)
  if (reach.value === null) return reach.error === null ? "not computed" : `not resolvable ${horizon}`;
  // a unit of several (metres and radians, one to one) in brackets
  const unit = reach.unit.includes(",") ? ` [${reach.unit}]` : ` ${reach.unit}`;
  let bound = "a lower bound"; // its error not known (JSON null)
  if (reach.error === 0) bound = "exact";
  else if (reach.error !== null) bound = `a lower bound: at most ${fmtG(reach.error, 2)} more`;
  return `${fmtG(reach.value, 4)}${unit} (${bound}) ${horizon}`;
}

function reachRow(reach) {
  const text = reachText(reach);
  return el("tr", { id: "reach", class: "reach", "data-value": reach ? reach.value : "", title: reach ? reach.budget : "" }, [
    el("td", { text: "r_T" }),
    el("td", {}, [el("span", { class: "label", text: "Reach margin " }), el("span", { text })]),
  ]);
}

function render(panel) {
  if (!pending) {
    // the controls follow the pose shown, unless newer moves wait to be sent:
    // then they hold those moves, and the pose shown is already out of date
    cdpm.natural = panel.natural.slice();
    panel.natural.forEach((value, i) => {
      const range = $(`slider-${i}`);
      const number = $(`value-${i}`);
      if (Number(range.value) !== value) range.value = value;
      if (document.activeElement !== number) number.value = fmt(value);
    });
    setActivePose(panel.pose);
  }
  $("q-text").textContent = panel.q_arguments;
  $("copy-note").textContent = "";

  const reason = $("reason");
  reason.hidden = !panel.reason;
  reason.textContent = panel.reason ? `Not analysed: ${panel.reason}` : "";

  const rows = panel.verdicts.map((v) => el("tr", { id: `verdict-${v.key}`, "data-verdict": v.verdict }, [
    el("td", {}, [badge(v.text, v.color)]),
    el("td", {}, [el("div", { class: "label", text: v.label }), el("div", { class: "detail", text: v.detail, title: v.detail })]),
  ]));
  rows.splice(1, 0, reachRow(panel.reach));  // the reach margin under the POC verdict
  $("verdict-table").tBodies[0].replaceChildren(...rows);
  $("notes").replaceChildren(...panel.notes.map((n) => el("li", { text: n })));

  $("cable-table").tBodies[0].replaceChildren(...panel.cables.map((c) => el("tr", { "data-cable": c.name, "data-state": c.state }, [
    el("td", {}, [el("span", { class: "swatch", style: `background:${c.color}` })]),
    el("td", { text: c.name }),
    el("td", { text: c.state }),
    el("td", { class: "num", text: c.tension === null ? "-" : fmt(c.tension, 3) }),
  ])));

  // a position output is its name; any other (orientation, joint, cable, sum) shows its formula
  $("output-table").tBodies[0].replaceChildren(...panel.outputs.map((o) => el("tr", { "data-output": o.name, "data-kind": o.kind }, [
    el("td", {}, [
      el("div", { text: o.name, title: o.definition }),
      ...(o.kind === "position" ? [] : [el("div", { class: "detail", text: o.definition, title: o.definition })]),
    ]),
    el("td", { class: "num", text: fmt(o.value) }),
    el("td", { text: o.unit }),
  ])));

  const root = $("panel");
  root.dataset.natural = JSON.stringify(panel.natural);
  root.dataset.seq = String(Number(root.dataset.seq) + 1);
}

// ------------------------------------------------------------------ start

async function start() {
  try {
    const response = await fetch("api/model");
    const model = await response.json();
    if (!response.ok) throw new Error(model.error || response.statusText);
    cdpm.model = model;
    document.title = `cdpm view: ${model.model}`;
    $("model-name").textContent = model.model;
    buildSliders(model.coordinates);
    buildPoses(model.poses);
    buildLegend(model.legend);
    buildMap(model.map);
    buildCopy();
    render(model.panel);
    $("update-time").textContent = "move a slider or pick a pose";
  } catch (error) {
    $("update-time").textContent = `cannot load the model: ${error.message}`;
    $("update-time").classList.add("error");
  }
}

start();
