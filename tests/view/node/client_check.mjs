// A third-party client of the live view (horus-view): Foxglove's own client library
// (@foxglove/ws-protocol's FoxgloveClient) over the `ws` WebSocket, decoding every message with
// the schema its channel advertised (JSON: JSON.parse; protobuf: protobufjs, from the
// advertisement's base64 FileDescriptorSet). Run by tests/view/test_view_clients.py, which reads
// the one JSON object this prints on stdout.
//
//   node client_check.mjs URL PLAN_JSON
//
// PLAN_JSON (every part optional):
//   {"subprotocols": ["foxglove.websocket.v1", ...],  each connected to in turn, the rest per each
//    "topics": ["cmd_vel", ...],                      wait until these are advertised
//    "subscribe": {"cmd_vel": 3, ...},                decode this many messages of each topic
//    "call": {"service": "scale", "request": {...}},  one JSON service call
//    "publish": {"topic": "cmd_in", "messages": [{...}, ...], "interval_ms": 20},
//    "measure": {"topics": ["fast"], "warmup_s": 1, "seconds": 5},  messages per second received
//    "time": {"count": 5},                            wait for this many of the server's `time`
//    "parameters": {"get": ["motor.max_speed"],       getParameters ([]: all), then
//                   "set": [{"name", "value"}, ...],  setParameters (with an id), then
//                   "watch": {"names": [...], "command": [ARGV...], "count": 1}}
//                                                     subscribeParameterUpdates, run ARGV (a
//                                                     program that changes one), and wait for
//                                                     this many parameterValues without an id
//    "tls": {"ca": PATH, "servername": "robot", "cert": PATH, "key": PATH},  for wss://: trust
//                                                     that CA, the server's certificate by its
//                                                     name; present cert and key when given
//    "timeout_ms": 15000}
// Prints {"runs": {SUBPROTOCOL: {...}}} with, per run: "protocol" (what the server chose),
// "serverInfo", "channels" (as advertised, without schemas), "services", "messages" ({topic:
// {"schemaName", "encoding", "decoded": [...], "timestamps": [...]}}, each decoded message's Message
// Data timestamp as a string of decimal nanoseconds), "call" ({"response"} or {"failure"}),
// "published", "measured" ({topic: {"count", "seconds", "rate", "bytes"}}), "times" (the first
// `time` messages' timestamps, strings of nanoseconds, with plan.time), "parameters" ({"get",
// "set": the answers' parameter lists, "services": the names of the services advertised, "updates": the parameterValues the subscription brought,
// "command": ARGV's exit status}), "statuses" (the server's
// status messages) and "error" (what went wrong, if anything). Exits 0 whenever it
// could print; the test judges the values.
import { execFileSync } from "node:child_process";
import fs from "node:fs";
// The package is CommonJS: its classes come from the default export.
import wsProtocol from "@foxglove/ws-protocol";
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, planText] = process.argv.slice(2);
if (!url || !planText) {
  console.error("usage: node client_check.mjs URL PLAN_JSON");
  process.exit(2);
}
const plan = JSON.parse(planText);
const timeoutMs = plan.timeout_ms ?? 15000;
const textEncoder = new TextEncoder();
const textDecoder = new TextDecoder();
// Byte fields longer than this are summarized (an image's pixels), not printed.
const PRINTED_BYTES = 16;

function within(promise, what) {
  let timer;
  const timeout = new Promise((_, reject) => {
    timer = setTimeout(() => reject(new Error(`timed out after ${timeoutMs} ms waiting for ${what}`)),
                       timeoutMs);
  });
  return Promise.race([promise, timeout]).finally(() => clearTimeout(timer));
}

const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

// The socket's TLS options (ws hands them to tls.connect): none without plan.tls.
function tlsOptions() {
  if (!plan.tls) return {};
  const { ca, servername, cert, key } = plan.tls;
  const options = { ca: fs.readFileSync(ca), servername };
  if (cert) Object.assign(options, { cert: fs.readFileSync(cert), key: fs.readFileSync(key) });
  return options;
}

// Bytes become {"length", "head", "sum"} so that a test can check an image's pixels.
function printable(value) {
  if (value instanceof Uint8Array) {
    let sum = 0;
    for (const byte of value) sum = (sum + byte) >>> 0;
    return { length: value.length, head: [...value.subarray(0, PRINTED_BYTES)], sum };
  }
  if (Array.isArray(value)) return value.map(printable);
  if (value !== null && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([key, item]) => [key, printable(item)]));
  }
  return value;
}

// One decoder per channel, made from what the channel advertised and nothing else.
function decoderFor(channel) {
  if (channel.encoding === "json") {
    return (data) => JSON.parse(textDecoder.decode(data));
  }
  if (channel.encoding === "protobuf") {
    if (channel.schemaEncoding !== "protobuf") {
      throw new Error(`channel ${channel.topic}: protobuf with schemaEncoding ${channel.schemaEncoding}`);
    }
    const set = descriptor.FileDescriptorSet.decode(Buffer.from(channel.schema, "base64"));
    // keepCase: the names Foxglove's .proto files give (frame_id), not protobufjs's camelCase.
    const type = protobuf.Root.fromDescriptor(set, { keepCase: true }).lookupType(channel.schemaName);
    return (data) => type.toObject(type.decode(data), { longs: String, enums: String, defaults: true });
  }
  throw new Error(`channel ${channel.topic}: no decoder for encoding ${channel.encoding}`);
}

function withoutSchema(channel) {
  const { schema, ...rest } = channel;
  return { ...rest, schemaLength: schema?.length ?? 0 };
}

async function run(subprotocol) {
  const result = { statuses: [] };
  const ws = new WebSocket(url, [subprotocol], tlsOptions());
  const client = new FoxgloveClient({ ws });
  const channels = new Map();         // topic -> channel
  const services = new Map();         // name -> service
  const handlers = new Map();         // subscription id -> (message) => void
  let serverInfo;
  const changed = [];                 // resolvers waiting for news
  const notify = () => changed.splice(0).forEach((resolve) => resolve());
  const until = async (predicate, what) => {
    await within((async () => {
      while (!predicate()) await new Promise((resolve) => changed.push(resolve));
    })(), what);
  };
  let closed = null;
  const times = [];                   // the server's `time` messages, as they came
  client.on("time", (message) => { times.push(String(message.timestamp)); notify(); });
  client.on("serverInfo", (info) => { serverInfo = info; notify(); });
  client.on("advertise", (list) => { for (const c of list) channels.set(c.topic, c); notify(); });
  client.on("unadvertise", (ids) => {
    for (const [topic, c] of channels) if (ids.includes(c.id)) channels.delete(topic);
    notify();
  });
  client.on("advertiseServices", (list) => { for (const s of list) services.set(s.name, s); notify(); });
  client.on("status", (status) => { result.statuses.push(status); notify(); });
  const parameterValues = [];         // the server's parameterValues, as they came
  client.on("parameterValues", (values) => { parameterValues.push(values); notify(); });
  // A message's data is a DataView; each handler gets its bytes. A message that does not decode
  // is the result's error, not a crash.
  let handlerError = null;
  client.on("message", (event) => {
    const bytes = new Uint8Array(event.data.buffer, event.data.byteOffset, event.data.byteLength);
    try {
      handlers.get(event.subscriptionId)?.(bytes, event.timestamp);
    } catch (error) {
      handlerError ??= `a message of subscription ${event.subscriptionId}: ${error.message ?? error}`;
      notify();
    }
  });
  client.on("error", (error) => { result.statuses.push({ clientError: String(error) }); notify(); });
  client.on("close", (event) => { closed = `closed: ${event.code} ${event.reason ?? ""}`; notify(); });
  try {
    await until(() => serverInfo !== undefined || closed, "serverInfo");
    if (closed) throw new Error(`the server ${closed} before its serverInfo`);
    result.protocol = ws.protocol;
    result.serverInfo = serverInfo;
    const topics = plan.topics ?? [];
    await until(() => topics.every((topic) => channels.has(topic)) || closed,
                `the advertisement of ${topics.join(", ")}`);
    if (closed) throw new Error(`the server ${closed}`);
    result.channels = [...channels.values()].map(withoutSchema);

    if (plan.subscribe) {
      result.messages = {};
      const pending = Object.entries(plan.subscribe).map(async ([topic, count]) => {
        const channel = channels.get(topic);
        if (!channel) throw new Error(`topic ${topic} is not advertised`);
        const decode = decoderFor(channel);
        const decoded = [];
        const timestamps = [];
        result.messages[topic] = {
          schemaName: channel.schemaName, encoding: channel.encoding, decoded, timestamps,
        };
        const id = client.subscribe(channel.id);
        handlers.set(id, (bytes, timestamp) => {
          if (decoded.length < count) {
            decoded.push(printable(decode(bytes)));
            timestamps.push(String(timestamp));
          }
          notify();
        });
        await until(() => decoded.length >= count || closed || handlerError,
                    `${count} messages of ${topic}`);
        if (handlerError) throw new Error(handlerError);
        client.unsubscribe(id);
        handlers.delete(id);
      });
      await Promise.all(pending);
    }

    if (plan.call) {
      // The service by its name, or by its type's name ("view_test.Scale" for "Scale").
      const wanted = plan.call.service;
      const find = () => [...services.values()].find((s) =>
        s.name === wanted || s.type === wanted || s.type?.endsWith(`.${wanted}`));
      await until(() => find() || closed, `the advertisement of service ${wanted}`);
      if (closed) throw new Error(`the server ${closed}`);
      const service = find();
      result.services = [...services.values()].map((s) => ({ id: s.id, name: s.name, type: s.type }));
      const callId = 1;
      let answer;
      client.on("serviceCallResponse", (response) => {
        if (response.callId !== callId) return;
        const data = new Uint8Array(response.data.buffer, response.data.byteOffset,
                                    response.data.byteLength);
        answer = { response: JSON.parse(textDecoder.decode(data)), encoding: response.encoding };
        notify();
      });
      client.on("serviceCallFailure", (failure) => {
        if (failure.callId !== callId) return;
        answer = { failure: failure.message };
        notify();
      });
      client.sendServiceCallRequest({
        serviceId: service.id, callId, encoding: "json",
        data: new DataView(textEncoder.encode(JSON.stringify(plan.call.request)).buffer),
      });
      await until(() => answer !== undefined || closed, `the answer to ${plan.call.service}`);
      result.call = answer;
    }

    if (plan.publish) {
      const { topic, messages, interval_ms: interval = 20 } = plan.publish;
      const advertised = channels.get(topic);
      const channelId = client.advertise({
        topic, encoding: "json", schemaName: advertised?.schemaName ?? "",
        schema: advertised?.schema, schemaEncoding: advertised?.schemaEncoding,
      });
      // The server learns of the channel before its first message; a short pause lets a
      // status refusing it arrive before the test reads the result.
      await sleep(100);
      for (const message of messages) {
        client.sendMessage(channelId, textEncoder.encode(JSON.stringify(message)));
        await sleep(interval);
      }
      await sleep(200);
      result.published = messages.length;
    }

    if (plan.measure) {
      const { topics: measured, warmup_s: warmup = 1, seconds = 5 } = plan.measure;
      const counts = Object.fromEntries(measured.map((topic) => [topic, { count: 0, bytes: 0 }]));
      let counting = false;
      for (const topic of measured) {
        const channel = channels.get(topic);
        if (!channel) throw new Error(`topic ${topic} is not advertised`);
        const id = client.subscribe(channel.id);
        handlers.set(id, (bytes) => {
          if (!counting) return;
          counts[topic].count += 1;
          counts[topic].bytes += bytes.byteLength;
        });
      }
      await sleep(warmup * 1000);
      counting = true;
      const start = performance.now();
      await sleep(seconds * 1000);
      counting = false;
      const elapsed = (performance.now() - start) / 1000;
      result.measured = Object.fromEntries(Object.entries(counts).map(([topic, c]) =>
        [topic, { ...c, seconds: elapsed, rate: c.count / elapsed }]));
    }

    if (plan.parameters) {
      const { get, set, watch } = plan.parameters;
      result.parameters = {};
      const answer = async (id, what) => {
        await until(() => parameterValues.some((values) => values.id === id) || closed, what);
        if (closed) throw new Error(`the server ${closed}`);
        return parameterValues.find((values) => values.id === id).parameters;
      };
      if (get) {
        client.getParameters(get, "get-1");
        result.parameters.get = await answer("get-1", "the answer to getParameters");
      }
      if (set) {
        client.setParameters(set, "set-1");
        result.parameters.set = await answer("set-1", "the answer to setParameters");
      }
      if (watch) {
        client.subscribeParameterUpdates(watch.names);
        // The server reads the subscription before the change the command makes.
        await sleep(200);
        try {
          execFileSync(watch.command[0], watch.command.slice(1), { stdio: "ignore" });
          result.parameters.command = 0;
        } catch (error) {
          result.parameters.command = error.status ?? String(error);
        }
        const updates = () => parameterValues.filter((values) => values.id === undefined);
        await until(() => updates().length >= (watch.count ?? 1) || closed,
                    "the parameter updates");
        result.parameters.updates = updates().map((values) => values.parameters);
        client.unsubscribeParameterUpdates(watch.names);
      }
      // The services offered beside them (a node's parameter service must not be one): the
      // server advertised them before it answered the first request.
      result.parameters.services = [...services.keys()];
    }

    if (plan.time) {
      const { count } = plan.time;
      await until(() => times.length >= count || closed, `${count} time messages`);
      result.times = times.slice(0, count);
    }
  } catch (error) {
    result.error = String(error.message ?? error);
  } finally {
    client.close();
  }
  return result;
}

const runs = {};
for (const subprotocol of plan.subprotocols ?? [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) {
  runs[subprotocol] = await run(subprotocol);
}
process.stdout.write(JSON.stringify({ runs }) + "\n");
process.exit(0);
