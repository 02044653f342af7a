// Reads an MCAP file with the TypeScript libraries Foxglove uses (@mcap/core, and for ROS 2 channels the
// ros2msg parser @foxglove/rosmsg and the CDR reader @foxglove/rosmsg2-serialization), decoding each CDR
// channel from the schema text stored in the file. Prints {topic: [{log_time, message}]} as JSON: arrays of
// numbers up to 64 values as lists, longer ones as {n, sum}; NaN as null.
const fs = require("fs");
const { McapIndexedReader } = require("@mcap/core");
const { loadDecompressHandlers } = require("@mcap/support");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
function plain(v) {
  if (ArrayBuffer.isView(v) || (Array.isArray(v) && v.every((x) => typeof x === "number"))) {
    const a = Array.from(v, Number);
    return a.length <= 64 ? a.map((x) => (Number.isNaN(x) ? null : x)) : { n: a.length, sum: a.reduce((s, x) => s + x, 0) };
  }
  if (Array.isArray(v)) return v.map(plain);
  if (typeof v === "bigint") return v.toString();
  if (typeof v === "number" && Number.isNaN(v)) return null;
  if (v && typeof v === "object") {
    const o = {};
    for (const [k, x] of Object.entries(v)) o[k] = plain(x);
    return o;
  }
  return v;
}
(async () => {
  const buf = fs.readFileSync(process.argv[2]);
  const readable = { size: async () => BigInt(buf.length),
    read: async (offset, length) => buf.subarray(Number(offset), Number(offset + length)) };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: await loadDecompressHandlers() });
  const readers = new Map();
  for (const [id, ch] of reader.channelsById) {
    const schema = reader.schemasById.get(ch.schemaId);
    if (ch.messageEncoding === "cdr" && schema.encoding === "ros2msg") {
      readers.set(id, new MessageReader(parse(new TextDecoder().decode(schema.data), { ros2: true })));
    }
  }
  const out = {};
  for await (const m of reader.readMessages()) {
    const r = readers.get(m.channelId);
    if (!r) continue;
    const topic = reader.channelsById.get(m.channelId).topic;
    (out[topic] = out[topic] || []).push({ log_time: m.logTime.toString(), message: plain(r.readMessage(m.data)) });
  }
  console.log(JSON.stringify(out));
})().catch((e) => { console.error(String(e)); process.exit(1); });
