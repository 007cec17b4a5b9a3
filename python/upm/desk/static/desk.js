// The upm desk page: the live camera with the tracked parts, their goals and the planned field;
// click a part then a point (goto), drag from a part (path), or use the buttons. Plain JavaScript.
"use strict";

const canvas = document.getElementById("plate");
const ctx = canvas.getContext("2d");
const statusLine = document.getElementById("status");
const errorLine = document.getElementById("error");
const image = new Image();
let state = null;
let selected = null; // id of the part clicked first
let drag = null;     // {id, points: [[u, v], ...]} while drawing a path
let socket = null;

function send(message) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
}

function connect() {
  socket = new WebSocket(`ws://${location.host}/ws`);
  socket.binaryType = "blob";
  socket.onmessage = (event) => {
    if (event.data instanceof Blob) {
      const url = URL.createObjectURL(event.data);
      image.onload = () => { URL.revokeObjectURL(url); draw(); };
      image.src = url;
      return;
    }
    const message = JSON.parse(event.data);
    if (message.type === "state") { state = message; draw(); showStatus(); }
    else if (message.type === "error") { errorLine.textContent = errorLine.title = message.message; }
    else if (message.type === "ack") { errorLine.textContent = errorLine.title = ""; }
  };
  socket.onclose = () => { statusLine.textContent = "disconnected: the plate is stopped"; };
}

function showStatus() {
  const seen = state.parts.filter((p) => !p.lost).length;
  statusLine.textContent = `${state.message} · ${seen} parts · plate time ${state.plate_time.toFixed(1)} s · ` +
    `${state.pulses} pulses` + (selected !== null ? ` · part ${selected} selected: click its goal` : "");
  statusLine.title = statusLine.textContent; // the line is clipped to keep the plate still
  document.getElementById("gather").disabled = !state.gather;
  document.getElementById("pause").textContent = state.paused ? "Resume" : "Pause";
}

function colour(label) {
  return { red: "#ff5252", blue: "#448aff", penny: "#c98a3a" }[label] || "#bbbbbb";
}

function draw() {
  if (image.width) {
    if (canvas.width !== image.width || canvas.height !== image.height) {
      canvas.width = image.width; canvas.height = image.height;
    }
    ctx.drawImage(image, 0, 0);
  }
  if (!state) return;
  ctx.lineWidth = 1.5;
  ctx.strokeStyle = "rgba(120, 220, 120, 0.8)";
  for (const [u, v, du, dv] of state.field_px) arrow(u, v, du, dv);
  for (const goal of state.goals) {
    ctx.strokeStyle = "#ffd54f";
    ctx.lineWidth = 2;
    if (goal.px) {
      cross(goal.px[0], goal.px[1], 8);
      const part = state.parts.find((p) => p.id === goal.id);
      if (part && part.px) line([part.px, goal.px], [4, 4]);
    } else if (goal.path_px) {
      line(goal.path_px, []);
    }
  }
  for (const part of state.parts) {
    if (!part.px) continue;
    ctx.beginPath();
    ctx.arc(part.px[0], part.px[1], state.radius_px + 3, 0, 2 * Math.PI);
    ctx.lineWidth = part.id === selected ? 4 : 2;
    ctx.strokeStyle = part.id === selected ? "#ffffff" : colour(part.label);
    ctx.stroke();
    ctx.fillStyle = "#ffffff";
    ctx.font = "13px sans-serif";
    ctx.fillText(`${part.id}`, part.px[0] + state.radius_px + 4, part.px[1] - state.radius_px);
  }
  if (drag && drag.points.length > 1) { ctx.strokeStyle = "#ffffff"; ctx.lineWidth = 2; line(drag.points, []); }
}

function arrow(u, v, du, dv) {
  const n = Math.hypot(du, dv);
  if (n < 1) return;
  ctx.beginPath();
  ctx.moveTo(u, v); ctx.lineTo(u + du, v + dv);
  const a = Math.atan2(dv, du), h = Math.min(6, n / 2);
  ctx.lineTo(u + du - h * Math.cos(a - 0.4), v + dv - h * Math.sin(a - 0.4));
  ctx.moveTo(u + du, v + dv);
  ctx.lineTo(u + du - h * Math.cos(a + 0.4), v + dv - h * Math.sin(a + 0.4));
  ctx.stroke();
}

function cross(u, v, r) {
  ctx.beginPath();
  ctx.moveTo(u - r, v - r); ctx.lineTo(u + r, v + r);
  ctx.moveTo(u - r, v + r); ctx.lineTo(u + r, v - r);
  ctx.stroke();
}

function line(points, dash) {
  ctx.setLineDash(dash);
  ctx.beginPath();
  points.forEach(([u, v], k) => (k ? ctx.lineTo(u, v) : ctx.moveTo(u, v)));
  ctx.stroke();
  ctx.setLineDash([]);
}

function at(event) { // the event's point in image pixels
  const box = canvas.getBoundingClientRect();
  return [(event.clientX - box.left) * canvas.width / box.width, (event.clientY - box.top) * canvas.height / box.height];
}

function partAt(point) {
  if (!state) return null;
  let best = null, bestDistance = 1.6 * state.radius_px + 4;
  for (const part of state.parts) {
    if (!part.px) continue;
    const d = Math.hypot(part.px[0] - point[0], part.px[1] - point[1]);
    if (d < bestDistance) { best = part.id; bestDistance = d; }
  }
  return best;
}

canvas.addEventListener("mousedown", (event) => {
  const point = at(event), id = partAt(point);
  drag = { id, start: point, points: [point] };
});

canvas.addEventListener("mousemove", (event) => {
  if (drag && drag.id !== null && event.buttons) { drag.points.push(at(event)); draw(); }
});

canvas.addEventListener("mouseup", (event) => {
  const point = at(event);
  const moved = drag ? Math.hypot(point[0] - drag.start[0], point[1] - drag.start[1]) : 0;
  if (drag && drag.id !== null && moved > 10 && drag.points.length > 2) {
    send({ type: "path", id: drag.id, path_px: drag.points });
    selected = null;
  } else {
    const id = partAt(point);
    if (selected === null) selected = id;           // first click: pick a part (or nothing)
    else if (id === selected) selected = null;      // the same part again: unpick it
    else if (id !== null) selected = id;            // another part: pick that one instead
    else { send({ type: "goto", id: selected, to_px: point }); selected = null; }
  }
  drag = null;
  draw();
  if (state) showStatus();
});

document.getElementById("sort").onclick = () => send({ type: "sort" });
document.getElementById("gather").onclick = () => send({ type: "gather" });
document.getElementById("clear").onclick = () => send({ type: "clear" });
document.getElementById("stop").onclick = () => send({ type: "stop" });
document.getElementById("pause").onclick = () => send({ type: state && state.paused ? "resume" : "pause" });
document.addEventListener("keydown", (event) => { if (event.key === "Escape") send({ type: "stop" }); });

setInterval(() => send({ type: "heartbeat" }), 200);
connect();
