// The ContextROS dashboard: renders each snapshot the server pushes over /ws.
// Everything shown comes from the ROS network, so it is only ever set as text.
"use strict";

const robots = document.getElementById("robots");
const connection = document.getElementById("connection");

function el(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(props)) {
    if (key === "text") node.textContent = value;
    else if (key === "cls") node.className = value;
    else node.setAttribute(key, value);
  }
  for (const child of children) if (child) node.append(child);
  return node;
}

function badge(text, kind, testid) {
  const props = { text, cls: `badge ${kind}` };
  if (testid) props["data-testid"] = testid;
  return el("span", props);
}

function table(header, rows, testid, empty) {
  if (!rows.length) return el("p", { cls: "empty", text: empty, "data-testid": testid });
  const head = el("tr", {}, ...header.map((h) => el("th", { text: h })));
  const body = rows.map((cells) => el("tr", {}, ...cells.map((c) =>
    c instanceof Node ? el("td", {}, c) : el("td", { text: String(c) }))));
  return el("table", { "data-testid": testid }, el("thead", {}, head), el("tbody", {}, ...body));
}

const STATE_KIND = { ok: "ok", lags: "warn", failed: "bad", twin: "bad", silent: "bad", left: "" };

function manager(robot) {
  const m = robot.manager;
  if (m.heard_ago === null) return badge("manager not heard yet", "bad", "manager");
  if (m.silent) return badge(`manager silent for ${m.heard_ago.toFixed(1)} s`, "bad", "manager");
  if (m.recovering) return badge("manager recovering", "warn", "manager");
  return badge("manager alive", "ok", "manager");
}

function holdCell(rule) {
  if (rule.error) return el("span", { cls: "error", text: `off: ${rule.error}` });
  if (rule.holding) {
    const done = rule.hold ? 100 * (1 - rule.hold_left / rule.hold) : 100;
    const bar = el("span", { cls: "hold" }, el("span", { style: `width: ${done.toFixed(0)}%` }));
    return el("span", {}, bar, ` ${rule.hold_left.toFixed(2)} of ${rule.hold} s`);
  }
  if (rule.relaxed) return el("span", { text: `hysteresis ${rule.hysteresis} engaged` });
  return el("span", { text: rule.hold ? `armed (hold ${rule.hold} s)` : "armed" });
}

function renderRobot(robot) {
  const section = el("section", { cls: "robot", "data-robot": robot.namespace });
  section.append(el("h2", { text: `robot ${robot.namespace}` }));
  const implied = robot.implied_by ?? {};
  const layers = robot.active.length
    ? robot.active.map((name) => implied[name]
      ? el("span", { cls: "layer implied", text: `${name} (implied by ${implied[name].join(", ")})` })
      : el("span", { cls: "layer", text: name }))
    : [el("span", { cls: "empty", text: "no layer active" })];
  const active = el("span", { "data-testid": "active" }, ...layers);
  const summary = el("div", { cls: "summary" },
    el("strong", { text: `epoch ${robot.epoch}`, "data-testid": "epoch" }), active,
    el("span", { cls: "why", text: `${robot.requester || "?"}: ${robot.reason || "-"}` }),
    manager(robot));
  if (robot.manager.lost_by.length)
    summary.append(badge(`manager_lost at ${robot.manager.lost_by.join(", ")}`, "bad", "manager-lost"));
  section.append(summary);

  section.append(el("h3", { text: "Nodes" }), table(
    ["node", "language", "state", "epoch", "lag", "critical section", "layers", "last heard"],
    robot.nodes.map((n) => [n.node, n.language, badge(n.state, STATE_KIND[n.state] ?? "", "node-state"),
      n.applied_epoch, n.lag ? `${n.lag} epoch(s)` : "", n.critical ? "yes" : "",
      n.layers.join(", "), `${n.heard_ago.toFixed(1)} s ago`]),
    "nodes", "no context node heard yet"));

  section.append(el("h3", { text: "Switches (newest first)" }), table(
    ["epoch", "time", "active", "by", "applied after (per node)"],
    robot.history.map((s) => [s.epoch, clockTime(s.published),
      withImplied(s.active, s.implied_by ?? {}) || "none", `${s.requester}: ${s.reason}`,
      Object.entries(s.latency_ms).map(([node, ms]) => `${node} ${ms.toFixed(1)} ms`).join(", ")]),
    "switches", "no switch since the dashboard started"));

  section.append(el("h3", { text: "Rules" }), table(
    ["rule", "condition now", "in force", "hold timer / hysteresis", "reads", "last firing"],
    robot.rules.map((r) => [el("span", { text: `${r.name}: ${r.text}`, title: r.where }),
      r.value, r.settled || "-", holdCell(r), r.readings.join("; "),
      r.last_firing ? `${r.last_firing}: ${r.last_outcome}` : "-"]),
    "rules", "the manager runs no rules"));

  section.append(el("h3", { text: "Bindings" }), actualLine(robot), table(
    ["layer", "node", "sets", "on drift", "seen on the node", "last result"],
    robot.bindings.map((b) => [b.layer, b.node,
      b.kind === "parameter" ? `${b.parameter} = ${b.value}` : `lifecycle ${b.value}`,
      b.policy || "report", seenCell(b),
      b.last_result ? el("span", { cls: b.ok ? "" : "error", text: `${b.ok ? "ok" : "FAILED"}: ${b.last_result}` }) : "-"]),
    "bindings", "no parameter or lifecycle bindings"));
  return section;
}

// Target (the active layers that set something) against actual (the layers whose bindings
// all hold on the nodes).
function actualLine(robot) {
  if (!robot.bindings.length) return "";
  const bound = new Set(robot.bindings.map((b) => b.layer));
  const target = robot.active.filter((name) => bound.has(name));
  const actual = robot.actual ?? [];
  const same = [...target].sort().join() === [...actual].sort().join();
  return el("div", { cls: "summary", "data-testid": "actual" },
    el("span", { text: `target [${target.join(", ") || "none"}]` }),
    el("span", { text: `actual [${actual.join(", ") || "none"}]` }),
    badge(same ? "as targeted" : "differs", same ? "ok" : "bad", "actual-state"));
}

// What the manager read on the node; a drift with since when and what was done about it.
function seenCell(b) {
  if (!b.observed) return "-";
  if (!b.drifted) return el("span", { text: b.holds ? `${b.observed} (holds)` : b.observed });
  const action = b.drift_action ? `; ${b.drift_action}` : "";
  return el("span", { cls: "error", "data-testid": "drift",
    text: `DRIFTED: ${b.observed} since ${clockTime(b.drifted_since)}${action}` });
}

// "CameraHigh (implied by Flight), Flight": the active layers, saying which are implied.
function withImplied(active, implied) {
  return active.map((name) => implied[name] ? `${name} (implied by ${implied[name].join(", ")})` : name)
    .join(", ");
}

// A switch's wall-clock time to the millisecond (switches come within ms of each other).
function clockTime(seconds) {
  const d = new Date(seconds * 1000);
  const two = (n) => String(n).padStart(2, "0");
  return `${two(d.getHours())}:${two(d.getMinutes())}:${two(d.getSeconds())}` +
    `.${String(d.getMilliseconds()).padStart(3, "0")}`;
}

function render(snapshot) {
  robots.replaceChildren(...snapshot.robots.map(renderRobot));
  document.body.dataset.version = snapshot.version;
}

let retry = 250;
function connect() {
  const socket = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
  socket.onopen = () => { retry = 250; connection.textContent = "live"; connection.className = "badge ok"; };
  socket.onmessage = (event) => render(JSON.parse(event.data));
  socket.onclose = () => {
    connection.textContent = "reconnecting"; connection.className = "badge bad";
    setTimeout(connect, retry);
    retry = Math.min(retry * 2, 5000);
  };
}
connect();
