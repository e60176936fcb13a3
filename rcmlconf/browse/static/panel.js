// The RCML browser's page: draws the panel the bridge describes and links its widgets to the
// bridge over one WebSocket (docs/browse.md). Everything of the RXID is shown as text, never run
// or parsed as HTML (R-RXID-30); which widget writes what is the bridge's to check.
"use strict";

const VERSION = 1;
const RETRY_MS = 1000;
const token = new URLSearchParams(location.search).get("token") || "";
// "robot path" -> the widgets that show that node.
let readers = new Map();
// widget key -> its note (refusals, in words, next to the widget).
let notes = new Map();
let robotStates = new Map();
let socket = null;

function el(tag, className, text) {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined && text !== null) node.textContent = text;
  return node;
}

function send(message) {
  if (socket && socket.readyState === WebSocket.OPEN) {
    socket.send(JSON.stringify(Object.assign({ v: VERSION }, message)));
  }
}

// A stream's values come at up to 62.5 Hz a page, most of them unchanged: a property set to what
// it already holds is left alone, so that Chromium has no style, layout or paint to redo for it.
function update(node, property, text) {
  if (node[property] !== text) node[property] = text;
}

function input(widget, value) {
  send({ type: "input", widget: widget.key, value: String(value) });
}

// -- drawing -------------------------------------------------------------------------------

function place(node, widget) {
  for (const [side, name] of [["left", "x"], ["top", "y"], ["width", "width"], ["height", "height"]]) {
    if (widget[name] !== null && widget[name] !== undefined) node.style[side] = widget[name] + "px";
  }
}

// Each maker returns [control, show(text)] (show is null for widgets that read nothing).
const makers = {
  box(w, box) {
    if (w.caption) box.append(el("span", "caption", w.caption));
    return [null, null];
  },
  label(w, box) {
    box.textContent = w.caption;
    return [null, null];
  },
  text(w) {
    const out = el("output");
    return [out, (text) => update(out, "textContent", text)];
  },
  button(w) {
    const button = el("button", null, w.caption || "");
    button.addEventListener("pointerdown", () => input(w, "press"));
    button.addEventListener("pointerup", () => input(w, "release"));
    button.addEventListener("keydown", (e) => {
      if (e.key === "Enter" || e.key === " ") { input(w, "press"); input(w, "release"); }
    });
    return [button, null];
  },
  checkbox(w, box) {
    const label = el("label");
    const check = el("input");
    check.type = "checkbox";
    check.disabled = !w.writes;
    check.addEventListener("change", () => input(w, check.checked ? "on" : "off"));
    label.append(check, " ", w.caption || "");
    box.append(label);
    return [null, (text) => { check.checked = text === w.on; }];
  },
  radioGroup(w, box) {
    const buttons = w.items.map((item) => {
      const label = el("label");
      const radio = el("input");
      radio.type = "radio";
      radio.name = w.key;
      radio.value = item.value;
      radio.disabled = !w.writes;
      radio.addEventListener("change", () => input(w, item.value));
      label.append(radio, " ", item.caption);
      box.append(label);
      return radio;
    });
    return [null, (text) => { for (const b of buttons) b.checked = b.value === text; }];
  },
  scroll(w) { return ranged(w); },
  slider(w) { return ranged(w); },
  edit(w) {
    const edit = el("input");
    edit.type = "text";
    edit.readOnly = !w.writes;
    edit.addEventListener("change", () => input(w, edit.value));
    // The robot's value does not overwrite what the user is typing.
    return [edit, (text) => { if (document.activeElement !== edit) update(edit, "value", text); }];
  },
  popUpMenu(w) {
    const select = el("select");
    select.disabled = !w.writes;
    select.append(el("option", null, ""));
    for (const item of w.items) {
      const option = el("option", null, item.caption);
      option.value = item.value;
      select.append(option);
    }
    select.addEventListener("change", () => input(w, select.value));
    return [select, (text) => { select.value = text; }];
  },
  netmeeting(w) {
    if (w.src) {
      const video = el("video");
      Object.assign(video, { src: w.src, autoplay: true, muted: true, controls: true });
      return [video, null];
    }
    return [el("div", "placeholder", "Video: " + (w.href || "no source") +
      " (this browser cannot play it)"), null];
  },
  html(w) {
    if (!w.src) return [el("div", "placeholder", "Page: " + w.href + " (not an http(s) URL)"), null];
    const frame = el("iframe");
    frame.sandbox = "";  // no script, no form, no navigation of this page
    frame.referrerPolicy = "no-referrer";
    frame.src = w.src;
    return [frame, null];
  },
  actionButton(w) {
    const button = el("button", null, w.caption || w.action);
    button.addEventListener("click", () => send({ type: "action", widget: w.key }));
    return [button, null];
  },
};

function ranged(w) {
  const range = el("input", w.orientation === "vertical" ? "vertical" : null);
  Object.assign(range, { type: "range", min: w.min, max: w.max, step: w.step });
  range.disabled = !w.writes;
  let dragging = false;
  range.addEventListener("pointerdown", () => { dragging = true; });
  range.addEventListener("pointerup", () => { dragging = false; });
  range.addEventListener("input", () => input(w, range.value));
  // D-RCTP-27: the slider must not jump back while it is dragged.
  return [range, (text) => {
    if (!dragging) { update(range, "value", text); update(range, "title", text); }
  }];
}

function drawWidget(w, area) {
  const box = el("div", "widget " + w.kind);
  box.dataset.key = w.key;
  if (w.id) box.dataset.rxidId = w.id;
  place(box, w);
  const [control, show] = makers[w.kind](w, box);
  if (control) box.append(control);
  const note = el("div", "note");
  box.append(note);
  notes.set(w.key, note);
  if (show && w.reads) {
    const key = w.robot + " " + w.path;
    if (!readers.has(key)) readers.set(key, []);
    readers.get(key).push(show);
  }
  area.append(box);
}

function drawPanel(panel) {
  readers = new Map();
  notes = new Map();
  document.title = panel.title;
  document.getElementById("title").textContent = panel.title;
  const desk = document.getElementById("desk");
  desk.replaceChildren();
  for (const win of panel.windows) {
    const frame = el("section", "window");
    if (win.id) frame.dataset.rxidId = win.id;
    frame.append(el("h2", null, win.title || panel.title));
    const area = el("div", "area");
    area.style.width = (win.width || 400) + "px";
    area.style.height = (win.height || 300) + "px";
    if (win.background) area.style.backgroundImage = "url(" + JSON.stringify(win.background) + ")";
    for (const w of win.widgets) drawWidget(w, area);
    frame.append(area);
    desk.append(frame);
  }
  const robots = document.getElementById("robots");
  robots.replaceChildren();
  robotStates = new Map();
  for (const robot of panel.robots) {
    const chip = el("span", "state connecting", robot.title + ": connecting");
    chip.dataset.robot = robot.robot;
    chip.title = robot.site;
    robots.append(chip);
    robotStates.set(robot.robot, { chip, title: robot.title });
  }
}

// -- what the bridge says ----------------------------------------------------------------

const handlers = {
  panel: drawPanel,
  values(m) {
    for (const [path, text] of Object.entries(m.values)) {
      for (const show of readers.get(m.robot + " " + path) || []) show(text);
    }
  },
  state(m) {
    const robot = robotStates.get(m.robot);
    if (!robot) return;
    robot.chip.className = "state " + m.state;
    robot.chip.dataset.state = m.state;
    robot.chip.textContent = robot.title + ": " + m.state + (m.detail ? " (" + m.detail + ")" : "");
  },
  stream(m) {
    addNote(m.path + ": stream " + m.state + (m.detail ? " (" + m.detail + ")" : ""));
  },
  refusal(m) {
    const note = notes.get(m.widget);
    if (note) note.textContent = m.text;
  },
  accepted(m) {
    const note = notes.get(m.widget);
    if (note) note.textContent = "";
  },
  refused(m) { addNote("message refused by the bridge: " + m.reason); },
  dropped(m) { addNote(m.count + " older notes dropped"); },
};

function addNote(text) {
  const list = document.getElementById("notes");
  list.prepend(el("li", null, text));
  while (list.children.length > 20) list.lastChild.remove();
}

function setLink(state, text) {
  const link = document.getElementById("link");
  link.className = "state " + state;
  link.dataset.state = state;
  link.textContent = text;
}

function connect() {
  const url = "ws://" + location.host + "/socket?token=" + encodeURIComponent(token);
  socket = new WebSocket(url);
  socket.addEventListener("open", () => setLink("open", "linked to rcmlconf browse"));
  socket.addEventListener("message", (event) => {
    let message;
    try { message = JSON.parse(event.data); } catch (e) { return; }
    if (message.v !== VERSION || !Object.hasOwn(handlers, message.type)) return;
    handlers[message.type](message);
  });
  socket.addEventListener("close", () => {
    setLink("reconnecting", "rcmlconf browse is gone: reconnecting");
    setTimeout(connect, RETRY_MS);
  });
}

connect();
