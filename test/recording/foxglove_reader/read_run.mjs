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

// Reads a run file as Foxglove does (@mcap/core's indexed reader, @foxglove/rosmsg's parser of
// the ros2msg schemas, @foxglove/rosmsg2-serialization's CDR reader) and prints, as JSON, every
// channel's schema and encodings, and every message decoded, by topic.
// Usage: node read_run.mjs RUN.mcap TOPIC...
import { readFile } from "node:fs/promises";

import { McapIndexedReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { decompress, isLoaded } from "@foxglove/wasm-zstd";

const [path, ...topics] = process.argv.slice(2);
const bytes = await readFile(path);
await isLoaded;
const reader = await McapIndexedReader.Initialize({
  readable: {
    size: async () => BigInt(bytes.byteLength),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  },
  decompressHandlers: { zstd: (data, size) => decompress(data, Number(size)) },
});
const channels = {};
const readers = new Map();
for (const channel of reader.channelsById.values()) {
  const schema = reader.schemasById.get(channel.schemaId);
  channels[channel.topic] = {
    messageEncoding: channel.messageEncoding,
    schemaName: schema?.name,
    schemaEncoding: schema?.encoding,
  };
  if (schema && schema.encoding === "ros2msg" && channel.messageEncoding === "cdr") {
    const definitions = parse(new TextDecoder().decode(schema.data), { ros2: true });
    readers.set(channel.id, new MessageReader(definitions));
  }
}
const messages = {};
for await (const message of reader.readMessages({ topics: topics.length ? topics : undefined })) {
  const channel = reader.channelsById.get(message.channelId);
  const decoded = readers.get(message.channelId).readMessage(message.data);
  (messages[channel.topic] ??= []).push({ logTime: message.logTime.toString(), message: decoded });
}
process.stdout.write(
  JSON.stringify({ profile: reader.header.profile, channels, messages }, (key, value) =>
    ArrayBuffer.isView(value) ? Array.from(value) : typeof value === "bigint" ? value.toString() : value,
  ),
);
