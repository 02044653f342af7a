// Reads an MCAP file with the TypeScript reader Foxglove uses (@mcap/core) and decodes its protobuf
// and JSON channels from the schemas stored in the file (protobufjs): counts and first values as JSON.
const fs = require("fs");
const { McapIndexedReader } = require("@mcap/core");
const { loadDecompressHandlers } = require("@mcap/support");
const protobuf = require("protobufjs");
const descriptor = require("protobufjs/ext/descriptor");
function parseChannel(ch, schema) {
  if (ch.messageEncoding === "json") return (d) => JSON.parse(new TextDecoder().decode(d));
  const root = protobuf.Root.fromDescriptor(descriptor.FileDescriptorSet.decode(schema.data));
  const type = root.lookupType(schema.name);
  return (d) => type.toObject(type.decode(d), { longs: String });
}
(async () => {
  const file = process.argv[2];
  const buf = fs.readFileSync(file);
  const readable = { size: async () => BigInt(buf.length),
    read: async (offset, length) => buf.subarray(Number(offset), Number(offset + length)) };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: await loadDecompressHandlers() });
  const counts = {}, decoded = {}, firsts = {};
  const parsers = new Map();
  for (const [id, ch] of reader.channelsById) {
    const schema = reader.schemasById.get(ch.schemaId);
    if (ch.messageEncoding === "protobuf" || ch.messageEncoding === "json") {
      parsers.set(id, parseChannel(ch, schema));
    }
  }
  for await (const m of reader.readMessages()) {
    const ch = reader.channelsById.get(m.channelId);
    counts[ch.topic] = (counts[ch.topic] || 0) + 1;
    const p = parsers.get(m.channelId);
    if (p) {
      const v = p(m.data);
      decoded[ch.topic] = (decoded[ch.topic] || 0) + 1;
      if (!(ch.topic in firsts)) firsts[ch.topic] = { log_time: m.logTime.toString(), value: v };
    }
  }
  console.log(JSON.stringify({ counts, decoded, firsts }, (k, v) => typeof v === "bigint" ? v.toString() :
    (v instanceof Uint8Array ? { bytes: v.length } : v)));
})().catch((e) => { console.error(String(e)); process.exit(1); });
