// Connects to a sweepline live view with @foxglove/ws-protocol's
// FoxgloveClient (which offers the subprotocol `foxglove.websocket.v1`),
// subscribes to a few channels and prints one JSON line with what it got.
//
// Usage: node live_client.mjs ws://127.0.0.1:PORT SECONDS
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, seconds] = [process.argv[2], Number(process.argv[3] ?? 10)];
const wanted = ["/scan", "/pose", "/tf", "/map", "/sweepline/status", "/log"];
const result = { protocol: null, serverName: null, capabilities: null, channels: {}, counts: {}, status: null, errors: [] };

function connect(deadline) {
  const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  ws.on("error", (e) => {
    if (Date.now() < deadline) {
      setTimeout(() => connect(deadline), 200);
    } else {
      result.errors.push(String(e));
      finish();
    }
  });
  ws.on("open", () => {
    result.protocol = ws.protocol;
    const client = new FoxgloveClient({ ws });
    const bySub = new Map();
    client.on("serverInfo", (info) => {
      result.serverName = info.name;
      result.capabilities = info.capabilities;
    });
    client.on("advertise", (channels) => {
      for (const ch of channels) {
        result.channels[ch.topic] = { schemaName: ch.schemaName, encoding: ch.encoding };
        if (wanted.includes(ch.topic)) {
          bySub.set(client.subscribe(ch.id), ch.topic);
        }
      }
    });
    client.on("message", ({ subscriptionId, data }) => {
      const topic = bySub.get(subscriptionId);
      result.counts[topic] = (result.counts[topic] ?? 0) + 1;
      if (topic === "/sweepline/status") {
        result.status = JSON.parse(new TextDecoder().decode(data));
      }
    });
    client.on("error", (e) => result.errors.push(String(e)));
    setTimeout(() => { client.close(); finish(); }, seconds * 1000);
  });
}

function finish() {
  console.log(JSON.stringify(result));
  process.exit(0);
}

connect(Date.now() + 30000);
