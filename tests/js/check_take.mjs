// Opens a Reenact take with @mcap/core, an MCAP reader written independently
// of ours, and prints what it finds as JSON on stdout:
//   {"mode", "channels": [{topic, schema_name, schema_encoding,
//    message_encoding, schema_bytes}], "counts": {topic: n},
//    "statistics_counts": {topic: n}, "message_count", "chunk_count",
//    "problems": [...]}
// Usage: node check_take.mjs FILE            (indexed reader: footer, summary)
//        node check_take.mjs --stream FILE   (streaming reader: works on
//                                             truncated files; reports where
//                                             it stopped)
// Exit status 0 when no problem was found, 1 otherwise, 2 on bad usage.
// Setup: npm ci --prefix tests/js   (or npm install --prefix tests/js)
import { open, readFile } from "node:fs/promises";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { decompress } from "fzstd";

const decompressHandlers = {
  zstd: (buffer, decompressedSize) => decompress(buffer, new Uint8Array(Number(decompressedSize))),
};

function describeChannels(channels, schemas, problems) {
  const out = [];
  for (const channel of channels.values()) {
    const schema = schemas.get(channel.schemaId);
    if (!schema) problems.push(`channel ${channel.topic} has no schema`);
    else if (schema.encoding !== "protobuf") {
      problems.push(`schema ${schema.name} has encoding ${schema.encoding}`);
    } else if (schema.data.length === 0) problems.push(`schema ${schema.name} is empty`);
    if (channel.messageEncoding !== "protobuf") {
      problems.push(`channel ${channel.topic} has message encoding ${channel.messageEncoding}`);
    }
    out.push({
      topic: channel.topic,
      schema_name: schema ? schema.name : "",
      schema_encoding: schema ? schema.encoding : "",
      message_encoding: channel.messageEncoding,
      schema_bytes: schema ? schema.data.length : 0,
    });
  }
  return out.sort((a, b) => (a.topic < b.topic ? -1 : a.topic > b.topic ? 1 : 0));
}

async function checkIndexed(path) {
  const handle = await open(path, "r");
  try {
    const readable = {
      size: async () => BigInt((await handle.stat()).size),
      read: async (offset, size) => {
        const buffer = new Uint8Array(Number(size));
        const { bytesRead } = await handle.read(buffer, 0, Number(size), Number(offset));
        if (bytesRead !== Number(size)) throw new Error(`short read at byte offset ${offset}`);
        return buffer;
      },
    };
    const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    const problems = [];
    const channels = describeChannels(reader.channelsById, reader.schemasById, problems);
    const counts = Object.fromEntries(channels.map((c) => [c.topic, 0]));
    let messageCount = 0;
    for await (const message of reader.readMessages()) {
      counts[reader.channelsById.get(message.channelId).topic] += 1;
      messageCount += 1;
    }
    const statisticsCounts = {};
    if (!reader.statistics) problems.push("no Statistics record");
    else {
      for (const [id, n] of reader.statistics.channelMessageCounts) {
        statisticsCounts[reader.channelsById.get(id).topic] = Number(n);
      }
    }
    return {
      mode: "indexed",
      channels,
      counts,
      statistics_counts: statisticsCounts,
      message_count: messageCount,
      chunk_count: reader.chunkIndexes.length,
      problems,
    };
  } finally {
    await handle.close();
  }
}

async function checkStream(path) {
  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(new Uint8Array(await readFile(path)));
  const channels = new Map();
  const schemas = new Map();
  const countsById = new Map();
  const problems = [];
  let messageCount = 0;
  try {
    for (let record; (record = reader.nextRecord()); ) {
      if (record.type === "Schema") schemas.set(record.id, record);
      else if (record.type === "Channel") channels.set(record.id, record);
      else if (record.type === "Message") {
        countsById.set(record.channelId, (countsById.get(record.channelId) ?? 0) + 1);
        messageCount += 1;
      }
    }
  } catch (error) {
    problems.push(`stream reader stopped: ${error.message}`);
  }
  if (!reader.done()) {
    problems.push(`file ends early: ${reader.bytesRemaining()} bytes left unparsed`);
  }
  const described = describeChannels(channels, schemas, problems);
  const counts = Object.fromEntries(described.map((c) => [c.topic, 0]));
  for (const [id, n] of countsById) counts[channels.get(id).topic] = n;
  return {
    mode: "stream",
    channels: described,
    counts,
    statistics_counts: {},
    message_count: messageCount,
    chunk_count: 0,
    problems,
  };
}

const args = process.argv.slice(2);
const stream = args[0] === "--stream";
const path = stream ? args[1] : args[0];
if (!path) {
  console.error("usage: node check_take.mjs [--stream] FILE");
  process.exit(2);
}
try {
  const result = stream ? await checkStream(path) : await checkIndexed(path);
  console.log(JSON.stringify(result));
  process.exit(result.problems.length === 0 ? 0 : 1);
} catch (error) {
  console.log(JSON.stringify({ mode: stream ? "stream" : "indexed", problems: [String(error)] }));
  process.exit(1);
}
