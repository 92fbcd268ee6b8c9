// The live view's built-in page: a Foxglove WebSocket protocol client (subprotocol
// foxglove.websocket.v1) of the server that serves this page, in plain JavaScript.
//
// What it subscribes to, and why: every channel whose encoding is "json" from the start, so that
// each row of the topic list shows a measured rate (messages are counted, not decoded, so a
// 1 kHz topic costs a counter); a binary channel (images, point clouds: "protobuf") only while it
// is the selected one, since its messages are large and the page cannot draw them. Only the
// selected topic's messages are decoded, for its newest value and the plot.
//
// Parameters (when the server has the capability): listed with getParameters every few seconds
// (nodes come and go), kept current with subscribeParameterUpdates, shown for the node chosen
// (clicking a node's row chooses it), and set with setParameters; a refusal comes back as a
// status with its reason, shown with the server's messages.
//
// Frames: the two frames channels ("/horus/frames", "/horus/frames_static") are json channels
// like any other, so they are subscribed to; their messages (one FrameTransform each) are decoded
// for the frames table: each frame's parent, whether it is static, and its measured rate.
//
// Page parameters: ?token=T is passed on to the WebSocket URL (and to the viewer links);
// ?topic=NAME&field=PATH select a topic and a plotted field at start; ?lichtblick=URL names the
// Lichtblick web app to link to (it is self-hosted; by default http://localhost:8080/, where its
// container serves).
//
// Stable hooks for tests (tests/view/test_view_page.py): #topics tr[data-topic][data-rate],
// #nodes tr[data-node][data-health], #value[data-topic][data-count], #plot[data-points]
// [data-field], #connection[data-state], #open-foxglove, #open-lichtblick,
// #parameters tr[data-parameter][data-value] (its input and its "set" button), #parameter-node,
// #frames tr[data-frame][data-parent][data-static][data-rate].
"use strict";

const SUBPROTOCOL = "foxglove.websocket.v1";
const OP_MESSAGE_DATA = 1;
const OP_TIME = 2;
// Rates are counts over a sliding window of RATE_BUCKETS buckets of RATE_BUCKET_MS each.
const RATE_BUCKET_MS = 250;
const RATE_BUCKETS = 8;
const PLOT_CAPACITY = 500;
// Array elements beyond this index are not offered as plot fields (an image's pixels would be).
const MAX_PLOTTED_ARRAY_INDEX = 16;
const RECONNECT_MAX_MS = 5000;
const RENDER_INTERVAL_MS = 100;
const PARAMETER_LIST_INTERVAL_MS = 2000;
const FRAMES_TOPIC = "/horus/frames";
const STATIC_FRAMES_TOPIC = "/horus/frames_static";

const params = new URLSearchParams(location.search);
const token = params.get("token");
const wsUrl = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/" +
    (token ? "?token=" + encodeURIComponent(token) : "");

const elements = {
  connection: document.getElementById("connection"),
  serverName: document.getElementById("server-name"),
  topics: document.querySelector("#topics tbody"),
  nodes: document.querySelector("#nodes tbody"),
  nodesNote: document.getElementById("nodes-note"),
  selectedTopic: document.getElementById("selected-topic"),
  value: document.getElementById("value"),
  field: document.getElementById("field"),
  plot: document.getElementById("plot"),
  log: document.getElementById("log"),
  parametersSection: document.getElementById("parameters-section"),
  parameters: document.querySelector("#parameters tbody"),
  parameterNode: document.getElementById("parameter-node"),
  framesSection: document.getElementById("frames-section"),
  frames: document.querySelector("#frames tbody"),
};

// Per connection: channels by id, subscriptions by id, the graph of nodes.
let socket = null;
let channels = new Map();        // channel id -> {channel, row, subscriptionId, window, pending}
let subscriptions = new Map();   // subscription id -> channel id
let nextSubscriptionId = 1;
let graph = emptyGraph();
let reconnectDelay = 250;
// Parameters by name ("NODE.PARAMETER") -> {name, value, type, row}; whether the server offers
// them and their updates.
let parameters = new Map();
let parametersOffered = false;
let parameterUpdatesOffered = false;
let nextParameterRequest = 1;
// Frames by child name -> {parent, isStatic, pending, window, rate}, as their messages tell them.
let frames = new Map();

// What the user chose; it survives reconnections.
let selectedTopic = params.get("topic");
let selectedField = params.get("field");
let newest = null;               // {channelId, payload} of the selected topic, not yet shown
let shownCount = 0;
let plotPoints = [];
let plotDirty = false;

function emptyGraph() {
  return {published: new Map(), subscribed: new Map(), services: new Map()};
}

function setViewerLinks() {
  const foxglove = "https://app.foxglove.dev/?ds=foxglove-websocket&ds.url=" +
      encodeURIComponent(wsUrl);
  document.getElementById("open-foxglove").href = foxglove;
  const lichtblick = new URL(params.get("lichtblick") || "http://localhost:8080/");
  lichtblick.searchParams.set("ds", "foxglove-websocket");
  lichtblick.searchParams.set("ds.url", wsUrl);
  document.getElementById("open-lichtblick").href = lichtblick.toString();
}

function setConnection(state, text) {
  elements.connection.dataset.state = state;
  elements.connection.textContent = text;
}

function log(level, text) {
  const item = document.createElement("li");
  item.dataset.level = level;
  item.textContent = new Date().toLocaleTimeString() + " " + text;
  elements.log.prepend(item);
  while (elements.log.children.length > 50) elements.log.lastChild.remove();
}

function connect() {
  setConnection("connecting", "connecting to " + wsUrl);
  socket = new WebSocket(wsUrl, [SUBPROTOCOL]);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => {
    reconnectDelay = 250;
    setConnection("open", "connected");
  };
  socket.onmessage = (event) => {
    if (typeof event.data === "string") {
      onJson(JSON.parse(event.data));
    } else {
      onBinary(new DataView(event.data));
    }
  };
  socket.onclose = (event) => {
    setConnection("closed", "disconnected (" + (event.reason || "code " + event.code) +
                  "), trying again");
    forgetConnection();
    setTimeout(connect, reconnectDelay);
    reconnectDelay = Math.min(reconnectDelay * 2, RECONNECT_MAX_MS);
  };
}

function send(message) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
}

function forgetConnection() {
  for (const entry of channels.values()) entry.row.remove();
  channels = new Map();
  subscriptions = new Map();
  graph = emptyGraph();
  renderNodes();
  for (const entry of parameters.values()) entry.row.remove();
  parameters = new Map();
  parametersOffered = false;
  parameterUpdatesOffered = false;
  frames = new Map();
  renderFrames();
}

function onJson(message) {
  switch (message.op) {
    case "serverInfo":
      elements.serverName.textContent = message.name ? "· " + message.name : "";
      if ((message.capabilities || []).includes("connectionGraph")) {
        send({op: "subscribeConnectionGraph"});
        elements.nodesNote.hidden = true;
      } else {
        elements.nodesNote.textContent = "This server does not report its nodes.";
        elements.nodesNote.hidden = false;
      }
      parametersOffered = (message.capabilities || []).includes("parameters");
      parameterUpdatesOffered = (message.capabilities || []).includes("parametersSubscribe");
      elements.parametersSection.hidden = !parametersOffered;
      listParameters();
      break;
    case "parameterValues":
      for (const parameter of message.parameters) showParameter(parameter);
      renderParameterNodes();
      break;
    case "advertise":
      for (const channel of message.channels) addChannel(channel);
      sortTopicRows();
      break;
    case "unadvertise":
      for (const id of message.channelIds) removeChannel(id);
      break;
    case "status":
      log(["info", "warning", "error"][message.level] || "info", message.message);
      break;
    case "connectionGraphUpdate":
      updateGraph(message);
      break;
    default:
      // Services, assets and the rest are for full viewers.
      break;
  }
}

function onBinary(view) {
  const opcode = view.getUint8(0);
  if (opcode !== OP_MESSAGE_DATA) return;  // OP_TIME: the page shows arrival, not server time
  const channelId = subscriptions.get(view.getUint32(1, true));
  const entry = channels.get(channelId);
  if (entry === undefined) return;  // a message of a subscription ended meanwhile
  entry.pending += 1;
  const topic = entry.channel.topic;
  if (topic === FRAMES_TOPIC || topic === STATIC_FRAMES_TOPIC) {
    noteFrame(new Uint8Array(view.buffer, view.byteOffset + 13, view.byteLength - 13),
              topic === STATIC_FRAMES_TOPIC);
  }
  if (entry.channel.topic === selectedTopic) {
    const payload = new Uint8Array(view.buffer, view.byteOffset + 13, view.byteLength - 13);
    newest = {channelId, payload};
    shownCount += 1;
    if (entry.channel.encoding === "json") addPlotPoint(payload);
  }
}

function addChannel(channel) {
  removeChannel(channel.id);
  const row = document.createElement("tr");
  row.dataset.topic = channel.topic;
  row.dataset.channel = channel.id;
  for (const text of [channel.topic, channel.schemaName, channel.encoding, "—"]) {
    const cell = document.createElement("td");
    cell.textContent = text;
    row.append(cell);
  }
  row.cells[0].className = "topic";
  row.cells[1].className = "type";
  row.cells[3].className = "rate";
  row.addEventListener("click", () => select(channel.topic));
  elements.topics.append(row);
  const entry = {channel, row, subscriptionId: null, window: [], pending: 0};
  channels.set(channel.id, entry);
  if (channel.encoding === "json" || channel.topic === selectedTopic) subscribe(entry);
  if (channel.topic === selectedTopic) markSelection();
}

function removeChannel(id) {
  const entry = channels.get(id);
  if (entry === undefined) return;
  if (entry.subscriptionId !== null) subscriptions.delete(entry.subscriptionId);
  entry.row.remove();
  channels.delete(id);
}

function sortTopicRows() {
  const rows = [...elements.topics.children];
  rows.sort((a, b) => a.dataset.topic.localeCompare(b.dataset.topic));
  elements.topics.append(...rows);
}

function subscribe(entry) {
  if (entry.subscriptionId !== null) return;
  entry.subscriptionId = nextSubscriptionId++;
  entry.window = [];
  // The bucket the subscription starts in holds only part of its messages: it is not counted.
  entry.partialBucket = true;
  subscriptions.set(entry.subscriptionId, entry.channel.id);
  send({op: "subscribe", subscriptions: [{id: entry.subscriptionId, channelId: entry.channel.id}]});
}

function unsubscribe(entry) {
  if (entry.subscriptionId === null) return;
  send({op: "unsubscribe", subscriptionIds: [entry.subscriptionId]});
  subscriptions.delete(entry.subscriptionId);
  entry.subscriptionId = null;
  entry.row.cells[3].textContent = "—";
  delete entry.row.dataset.rate;
}

function select(topic) {
  if (topic === selectedTopic) return;
  for (const entry of channels.values()) {
    // A binary channel is received only while selected.
    if (entry.channel.topic === selectedTopic && entry.channel.encoding !== "json") {
      unsubscribe(entry);
    }
  }
  selectedTopic = topic;
  selectedField = null;
  newest = null;
  shownCount = 0;
  clearPlot();
  elements.field.replaceChildren();
  elements.value.textContent = "";
  for (const entry of channels.values()) {
    if (entry.channel.topic === topic) subscribe(entry);
  }
  markSelection();
}

function markSelection() {
  for (const entry of channels.values()) {
    entry.row.classList.toggle("selected", entry.channel.topic === selectedTopic);
  }
  elements.selectedTopic.textContent = selectedTopic || "(click a topic)";
  elements.value.dataset.topic = selectedTopic || "";
}

// Rates: every bucket, each subscribed channel's count moves into its window.
function tickRates() {
  for (const entry of channels.values()) {
    if (entry.subscriptionId === null) continue;
    if (entry.partialBucket) {
      entry.partialBucket = false;
      entry.pending = 0;
      continue;
    }
    entry.window.push(entry.pending);
    entry.pending = 0;
    if (entry.window.length > RATE_BUCKETS) entry.window.shift();
    const seconds = entry.window.length * RATE_BUCKET_MS / 1000;
    const rate = entry.window.reduce((sum, count) => sum + count, 0) / seconds;
    entry.rate = rate;
    entry.row.dataset.rate = rate.toFixed(1);
    entry.row.cells[3].textContent = rate >= 10 ? rate.toFixed(0) : rate.toFixed(1);
  }
  for (const frame of frames.values()) {
    frame.window.push(frame.pending);
    frame.pending = 0;
    if (frame.window.length > RATE_BUCKETS) frame.window.shift();
    frame.rate = frame.window.reduce((sum, count) => sum + count, 0) /
        (frame.window.length * RATE_BUCKET_MS / 1000);
  }
  renderNodes();
  renderFrames();
}

// One FrameTransform of a frames channel: its frame is listed, or its entry updated.
function noteFrame(payload, isStatic) {
  let transform;
  try {
    transform = JSON.parse(textDecoder.decode(payload));
  } catch (error) {
    return;
  }
  let frame = frames.get(transform.child_frame_id);
  if (frame === undefined) {
    frame = {pending: 0, window: [], rate: undefined};
    frames.set(transform.child_frame_id, frame);
  }
  frame.parent = transform.parent_frame_id;
  frame.isStatic = isStatic;
  frame.pending += 1;
}

function renderFrames() {
  elements.framesSection.hidden = frames.size === 0;
  const rows = [];
  for (const name of [...frames.keys()].sort()) {
    const frame = frames.get(name);
    const row = document.createElement("tr");
    row.dataset.frame = name;
    row.dataset.parent = frame.parent;
    row.dataset.static = String(frame.isStatic);
    // A static frame is sent once (and again when the static set changes): it has no rate.
    const rate = frame.isStatic || frame.rate === undefined ? "—" :
        frame.rate >= 10 ? frame.rate.toFixed(0) : frame.rate.toFixed(1);
    if (!frame.isStatic && frame.rate !== undefined) row.dataset.rate = frame.rate.toFixed(1);
    for (const text of [name, frame.parent, frame.isStatic ? "static" : "", rate]) {
      const cell = document.createElement("td");
      cell.textContent = text;
      row.append(cell);
    }
    row.cells[3].className = "rate";
    rows.push(row);
  }
  elements.frames.replaceChildren(...rows);
}

function updateGraph(update) {
  for (const topic of update.publishedTopics || []) {
    graph.published.set(topic.name, topic.publisherIds || []);
  }
  for (const topic of update.subscribedTopics || []) {
    graph.subscribed.set(topic.name, topic.subscriberIds || []);
  }
  for (const service of update.advertisedServices || []) {
    graph.services.set(service.name, service.providerIds || []);
  }
  for (const name of update.removedTopics || []) {
    graph.published.delete(name);
    graph.subscribed.delete(name);
  }
  for (const name of update.removedServices || []) graph.services.delete(name);
  renderNodes();
}

function topicRate(topic) {
  for (const entry of channels.values()) {
    if (entry.channel.topic === topic && entry.rate !== undefined &&
        entry.subscriptionId !== null) {
      return entry.rate;
    }
  }
  return undefined;
}

// A node's health, from what the graph and the measured rates say: "publishing" when one of its
// topics is flowing, "silent" when every topic of it whose rate is measured has stopped, else
// "present" (it is in the graph: registered and not yet gone).
function nodeHealth(node) {
  const rates = node.publishes.map(topicRate).filter((rate) => rate !== undefined);
  if (rates.some((rate) => rate > 0)) return "publishing";
  if (rates.length > 0) return "silent";
  return "present";
}

function renderNodes() {
  const nodes = new Map();
  const nodeOf = (id) => {
    if (!nodes.has(id)) nodes.set(id, {id, publishes: [], subscribes: [], serves: []});
    return nodes.get(id);
  };
  for (const [topic, ids] of graph.published) for (const id of ids) nodeOf(id).publishes.push(topic);
  for (const [topic, ids] of graph.subscribed) for (const id of ids) nodeOf(id).subscribes.push(topic);
  for (const [service, ids] of graph.services) for (const id of ids) nodeOf(id).serves.push(service);
  const rows = [];
  for (const node of [...nodes.values()].sort((a, b) => String(a.id).localeCompare(String(b.id)))) {
    const row = document.createElement("tr");
    row.dataset.node = node.id;
    const health = nodeHealth(node);
    row.dataset.health = health;
    for (const text of [node.id, node.publishes.join(", "), node.subscribes.join(", "),
                        node.serves.join(", "), health]) {
      const cell = document.createElement("td");
      cell.textContent = text;
      row.append(cell);
    }
    row.cells[4].className = "health";
    // Chooses the node whose parameters are shown, when it has any.
    row.addEventListener("click", () => {
      if (![...elements.parameterNode.options].some((option) => option.value === node.id)) return;
      elements.parameterNode.value = node.id;
      filterParameters();
    });
    rows.push(row);
  }
  elements.nodes.replaceChildren(...rows);
}

function listParameters() {
  if (parametersOffered) {
    send({op: "getParameters", parameterNames: [], id: "page-" + nextParameterRequest++});
  }
}

// A parameter as getParameters, setParameters or an update tells it: its row made or updated.
function showParameter(parameter) {
  let entry = parameters.get(parameter.name);
  if (entry === undefined) {
    const row = document.createElement("tr");
    row.dataset.parameter = parameter.name;
    const name = document.createElement("td");
    name.textContent = parameter.name;
    const input = document.createElement("input");
    const button = document.createElement("button");
    button.textContent = "set";
    button.className = "set";
    const valueCell = document.createElement("td");
    valueCell.append(input);
    const buttonCell = document.createElement("td");
    buttonCell.append(button);
    row.append(name, valueCell, buttonCell);
    entry = {name: parameter.name, row, input};
    button.addEventListener("click", () => setParameter(entry));
    input.addEventListener("keydown", (event) => {
      if (event.key === "Enter") setParameter(entry);
    });
    parameters.set(parameter.name, entry);
    const rows = [...elements.parameters.children, row];
    rows.sort((a, b) => a.dataset.parameter.localeCompare(b.dataset.parameter));
    elements.parameters.append(...rows);
    if (parameterUpdatesOffered) {
      send({op: "subscribeParameterUpdates", parameterNames: [parameter.name]});
    }
  }
  entry.value = parameter.value;
  entry.type = parameter.type;
  const text = typeof parameter.value === "string" ? parameter.value :
      JSON.stringify(parameter.value);
  entry.row.dataset.value = text;
  // The text being edited is left alone.
  if (document.activeElement !== entry.input) entry.input.value = text;
  entry.row.hidden = !parameterVisible(parameter.name);
}

// A string parameter takes the text as typed; any other, the text read as JSON.
function setParameter(entry) {
  const text = entry.input.value;
  let value = text;
  if (typeof entry.value !== "string") {
    try {
      value = JSON.parse(text);
    } catch (error) {
      log("error", entry.name + ": '" + text + "' is not a value (" + error.message + ")");
      return;
    }
  }
  const parameter = {name: entry.name, value};
  if (entry.type) parameter.type = entry.type;
  entry.input.blur();
  send({op: "setParameters", parameters: [parameter], id: "page-" + nextParameterRequest++});
}

// "NODE.PARAMETER": the node is everything before the last dot.
function parameterNodeOf(name) {
  return name.slice(0, name.lastIndexOf("."));
}

function parameterVisible(name) {
  const node = elements.parameterNode.value;
  return node === "" || parameterNodeOf(name) === node;
}

function renderParameterNodes() {
  const nodes = [...new Set([...parameters.keys()].map(parameterNodeOf))].sort();
  const offered = [...elements.parameterNode.options].slice(1).map((option) => option.value);
  if (nodes.join("\n") === offered.join("\n")) return;
  const chosen = elements.parameterNode.value;
  elements.parameterNode.replaceChildren(new Option("every node", ""),
                                         ...nodes.map((node) => new Option(node, node)));
  elements.parameterNode.value = nodes.includes(chosen) ? chosen : "";
}

function filterParameters() {
  for (const entry of parameters.values()) entry.row.hidden = !parameterVisible(entry.name);
}

elements.parameterNode.addEventListener("change", filterParameters);

// Every number of a decoded message, by path ("linear", "origin.x", "values[2].value"); u64 and
// i64 come as decimal strings (JSON numbers are doubles) and are plotted as numbers too.
function numericFields(value, path, out) {
  if (typeof value === "number") {
    out.push({path, value, exact: true});
  } else if (typeof value === "string" && /^-?\d+$/.test(value) && path) {
    out.push({path, value: Number(value), exact: false});
  } else if (Array.isArray(value)) {
    value.slice(0, MAX_PLOTTED_ARRAY_INDEX).forEach(
        (item, index) => numericFields(item, path + "[" + index + "]", out));
  } else if (value !== null && typeof value === "object") {
    for (const [key, item] of Object.entries(value)) {
      numericFields(item, path ? path + "." + key : key, out);
    }
  }
  return out;
}

const textDecoder = new TextDecoder();

function addPlotPoint(payload) {
  let message;
  try {
    message = JSON.parse(textDecoder.decode(payload));
  } catch (error) {
    return;  // shown as undecodable by renderValue
  }
  const fields = numericFields(message, "", []);
  if (elements.field.options.length !== fields.length) offerFields(fields);
  const field = fields.find((candidate) => candidate.path === selectedField);
  if (field === undefined) return;
  plotPoints.push(field.value);
  if (plotPoints.length > PLOT_CAPACITY) plotPoints.shift();
  plotDirty = true;
}

function offerFields(fields) {
  elements.field.replaceChildren(...fields.map((field) => new Option(field.path, field.path)));
  if (!fields.some((field) => field.path === selectedField)) {
    // By default the first plain number: a stamp (u64 as a string) is a poor first plot.
    const first = fields.find((field) => field.exact) || fields[0];
    selectedField = first ? first.path : null;
  }
  elements.field.value = selectedField || "";
  elements.plot.dataset.field = selectedField || "";
}

elements.field.addEventListener("change", () => {
  selectedField = elements.field.value;
  elements.plot.dataset.field = selectedField;
  clearPlot();
});

function clearPlot() {
  plotPoints = [];
  plotDirty = true;
}

function renderValue() {
  if (newest === null) return;
  const entry = channels.get(newest.channelId);
  const {payload} = newest;
  newest = null;
  if (entry === undefined) return;
  let text;
  if (entry.channel.encoding === "json") {
    try {
      text = JSON.stringify(JSON.parse(textDecoder.decode(payload)), null, 2);
    } catch (error) {
      text = "(a message that is not JSON: " + error.message + ")";
    }
  } else {
    text = entry.channel.schemaName + " message of " + payload.byteLength + " bytes (" +
        entry.channel.encoding + "): open it in Foxglove to see it drawn";
  }
  elements.value.textContent = text;
  elements.value.dataset.count = String(shownCount);
}

function renderPlot() {
  if (!plotDirty) return;
  plotDirty = false;
  const canvas = elements.plot;
  canvas.dataset.points = String(plotPoints.length);
  const context = canvas.getContext("2d");
  const {width, height} = canvas;
  context.clearRect(0, 0, width, height);
  if (plotPoints.length === 0) return;
  let low = Math.min(...plotPoints);
  let high = Math.max(...plotPoints);
  if (high === low) {
    high += 1;
    low -= 1;
  }
  const margin = 16;
  const x = (index) => margin + (width - 2 * margin) * index / Math.max(PLOT_CAPACITY - 1, 1);
  const y = (value) => height - margin - (height - 2 * margin) * (value - low) / (high - low);
  context.strokeStyle = "#888";
  context.fillStyle = "#444";
  context.font = "12px sans-serif";
  context.fillText(high.toPrecision(6), 2, margin - 4);
  context.fillText(low.toPrecision(6), 2, height - 2);
  context.strokeStyle = "#1f6feb";
  context.lineWidth = 1.5;
  context.beginPath();
  plotPoints.forEach((value, index) => {
    if (index === 0) context.moveTo(x(index), y(value));
    else context.lineTo(x(index), y(value));
  });
  context.stroke();
}

// On a timer rather than animation frames, which stop in a hidden tab: the value and plot are
// current when the tab is shown again.
function render() {
  renderValue();
  renderPlot();
}

setViewerLinks();
markSelection();
connect();
setInterval(tickRates, RATE_BUCKET_MS);
setInterval(render, RENDER_INTERVAL_MS);
setInterval(listParameters, PARAMETER_LIST_INTERVAL_MS);
