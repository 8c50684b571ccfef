// Copyright 2026 qrm_ros developers
//
// Licensed under the Apache License, Version 2.0 (the "License");
// you may not use this file except in compliance with the License.
// You may obtain a copy of the License at
//
//     http://www.apache.org/licenses/LICENSE-2.0
//
// Unless required by applicable law or agreed to in writing, software
// distributed under the License is distributed on an "AS IS" BASIS,
// WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
// See the License for the specific language governing permissions and
// limitations under the License.

// Foxglove's own protocol client, driven by the tests and the bridge benchmark.
//
// node foxglove_ws_client.js ws://127.0.0.1:PORT
// Commands come on stdin, one JSON object a line; what the server says goes to stdout, one JSON
// object a line. Messages are decoded with Foxglove's ROS 2 CDR reader from the channel's own
// ros2msg schema, as the Foxglove app decodes them. The modules come from NODE_PATH.
//
//   {"op": "subscribe", "topic": "/joint_states"}      (waits for the channel to be advertised)
//   {"op": "unsubscribe", "topic": "/joint_states"}
//   {"op": "getParameters", "names": [...]}            {"op": "setParameters", "parameters": [...]}
//   {"op": "subscribeParameterUpdates", "names": [...]}
//   {"op": "call", "service": "/shaper_sim/pause", "request": {"data": true}}
//   {"op": "advertise", "topic": "input_speed_cmd", "schemaName": "std_msgs/msg/Float64",
//    "schema": "float64 data"}
//   {"op": "publish", "topic": "input_speed_cmd", "message": {"data": 3.0}}
//   {"op": "publishBytes", "topic": "input_speed_cmd", "hex": "0001"}
//   {"op": "stall", "seconds": 5}       (blocks this process: it reads nothing meanwhile)
//   {"op": "count"}                     (prints how many messages arrived, by topic)
//   {"op": "quiet", "topic": "/joint_states"}   (count that topic's messages, print none)
//   {"op": "report"}                    (counts, and the quiet topics' stamps and latencies)
//   {"op": "fetchAsset", "uri": "package://qrm_ros/urdf/qrm_shaper.urdf"}
//   {"op": "raw", "text": "..."}          (sent as it is: a malformed message, say)
//   {"op": "close"}

'use strict';

const readline = require('readline');
const { FoxgloveClient } = require('@foxglove/ws-protocol');
const { parse } = require('@foxglove/rosmsg');
const { MessageReader, MessageWriter } = require('@foxglove/rosmsg2-serialization');

// The SDK's server speaks foxglove.sdk.v1; offering it beside the client's own name connects.
const SUBPROTOCOLS = [FoxgloveClient.SUPPORTED_SUBPROTOCOL, 'foxglove.sdk.v1'];

function plain(key, value) {
  if (ArrayBuffer.isView(value)) return Array.from(value, (v) => (typeof v === 'bigint' ? Number(v) : v));
  if (typeof value === 'bigint') return Number(value);
  return value;
}

function say(event) {
  process.stdout.write(JSON.stringify(event, plain) + '\n');
}

const socket = new WebSocket(process.argv[2], SUBPROTOCOLS);
const client = new FoxgloveClient({ ws: socket });
const channels = new Map(); // topic -> channel
const readers = new Map(); // channel id -> {topic, reader}
const subscriptions = new Map(); // topic -> subscription id
const bySubscription = new Map(); // subscription id -> channel id
const waiting = new Map(); // topic -> commands waiting for the channel
const services = new Map(); // name -> service
const calls = new Map(); // call id -> service
const published = new Map(); // topic -> {id, writer}
const counts = {};
const quiet = new Set();
const stamps = {}; // quiet topic -> header stamps 'sec.nanosec'
const latencies = {}; // quiet topic -> stamp-to-arrival times, ms
let nextCall = 1;
let nextAsset = 1;

function subscribe(topic) {
  const channel = channels.get(topic);
  if (!channel) {
    waiting.set(topic, (waiting.get(topic) || []).concat([topic]));
    return;
  }
  const id = client.subscribe(channel.id);
  subscriptions.set(topic, id);
  bySubscription.set(id, channel.id);
  readers.set(channel.id, { topic, reader: new MessageReader(parse(channel.schema, { ros2: true })) });
  say({ event: 'subscribed', topic });
}

client.on('open', () => say({ event: 'open' }));
client.on('error', (error) => say({ event: 'error', text: String(error && error.message || error) }));
client.on('close', (event) => { say({ event: 'close', code: event.code }); process.exit(0); });
client.on('serverInfo', (info) => say({ event: 'serverInfo', name: info.name, capabilities: info.capabilities }));
client.on('status', (status) => say({ event: 'status', level: status.level, message: status.message }));
client.on('advertise', (advertised) => {
  for (const channel of advertised) {
    channels.set(channel.topic, channel);
    say({ event: 'advertise', topic: channel.topic, encoding: channel.encoding,
          schemaName: channel.schemaName, schemaEncoding: channel.schemaEncoding,
          schema: channel.schema });
    if (waiting.has(channel.topic)) {
      waiting.delete(channel.topic);
      subscribe(channel.topic);
    }
  }
});
client.on('unadvertise', (ids) => {
  for (const [topic, channel] of channels) {
    if (ids.includes(channel.id)) {
      channels.delete(topic);
      say({ event: 'unadvertise', topic });
    }
  }
});
// Wall-clock time in ms with sub-millisecond resolution, comparable with ROS header stamps.
const wallMs = () => performance.timeOrigin + performance.now();

client.on('message', ({ subscriptionId, data }) => {
  const received = wallMs();
  const entry = readers.get(bySubscription.get(subscriptionId));
  if (!entry) return;
  counts[entry.topic] = (counts[entry.topic] || 0) + 1;
  if (quiet.has(entry.topic)) {
    // Quiet: keep each stamped message's stamp and delivery latency (stamp to here), in ms.
    const { header } = entry.reader.readMessage(data);
    if (header) {
      const stamp = header.stamp.sec * 1e3 + header.stamp.nanosec / 1e6;
      (stamps[entry.topic] = stamps[entry.topic] || []).push(
        `${header.stamp.sec}.${String(header.stamp.nanosec).padStart(9, '0')}`);
      (latencies[entry.topic] = latencies[entry.topic] || []).push(received - stamp);
    }
    return;
  }
  say({ event: 'message', topic: entry.topic, wallMs: received, message: entry.reader.readMessage(data) });
});
client.on('parameterValues', ({ parameters, id }) => say({ event: 'parameterValues', id, parameters }));
client.on('advertiseServices', (advertised) => {
  for (const service of advertised) {
    services.set(service.name, service);
    say({ event: 'advertiseService', name: service.name, type: service.type });
  }
});
client.on('serviceCallResponse', (response) => {
  const service = calls.get(response.callId);
  const reader = new MessageReader(parse(service.response.schema, { ros2: true }));
  say({ event: 'serviceCallResponse', service: service.name, response: reader.readMessage(response.data) });
});
client.on('serviceCallFailure', ({ callId, message }) =>
  say({ event: 'serviceCallFailure', service: (calls.get(callId) || {}).name, message }));
client.on('fetchAssetResponse', (response) =>
  say({ event: 'fetchAssetResponse', status: response.status, error: response.error,
        text: response.data ? Buffer.from(response.data.buffer, response.data.byteOffset,
                                          response.data.byteLength).toString('utf8') : null }));

function run(command) {
  switch (command.op) {
    case 'subscribe': subscribe(command.topic); break;
    case 'unsubscribe': client.unsubscribe(subscriptions.get(command.topic)); break;
    case 'getParameters': client.getParameters(command.names, command.id); break;
    case 'setParameters': client.setParameters(command.parameters, command.id); break;
    case 'subscribeParameterUpdates': client.subscribeParameterUpdates(command.names); break;
    case 'call': {
      const service = services.get(command.service);
      if (!service) { say({ event: 'error', text: `no service ${command.service}` }); break; }
      const writer = new MessageWriter(parse(service.request.schema, { ros2: true }));
      const callId = nextCall++;
      calls.set(callId, service);
      client.sendServiceCallRequest({ serviceId: service.id, callId, encoding: 'cdr',
                                      data: writer.writeMessage(command.request) });
      break;
    }
    case 'advertise': {
      const id = client.advertise({ topic: command.topic, encoding: 'cdr', schemaName: command.schemaName,
                                    schemaEncoding: 'ros2msg', schema: command.schema });
      published.set(command.topic, { id, writer: new MessageWriter(parse(command.schema, { ros2: true })) });
      break;
    }
    case 'publish': {
      const { id, writer } = published.get(command.topic);
      client.sendMessage(id, writer.writeMessage(command.message));
      break;
    }
    case 'publishBytes': client.sendMessage(published.get(command.topic).id, Buffer.from(command.hex, 'hex')); break;
    case 'stall': Atomics.wait(new Int32Array(new SharedArrayBuffer(4)), 0, 0, command.seconds * 1000); break;
    case 'count': say({ event: 'count', counts }); break;
    case 'report': say({ event: 'report', counts, stamps, latencies }); break;
    case 'quiet': quiet.add(command.topic); break;
    case 'fetchAsset': client.fetchAsset(command.uri, nextAsset++); break;
    case 'raw': socket.send(command.text); break;
    case 'close': client.close(); break;
    default: say({ event: 'error', text: `unknown op ${command.op}` });
  }
}

readline.createInterface({ input: process.stdin }).on('line', (line) => {
  if (line.trim()) run(JSON.parse(line));
});
