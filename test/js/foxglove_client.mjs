// A Foxglove WebSocket client in Node: @foxglove/ws-protocol's FoxgloveClient (npm, pinned in package.json) over
// the `ws` package, driven by test/integration/test_foxglove.py. It runs the steps given on the command line, in
// order, each a JSON object {"do": ..., ...}, and prints one JSON line per result ({"step": ..., ...}) on stdout.
// Bytes go as base64. Usage: node foxglove_client.mjs ws://127.0.0.1:PORT '{"do": "info"}' ...
import wsProtocol from '@foxglove/ws-protocol'; // (CommonJS: its exports are the default's)
import WebSocket from 'ws';

const {FoxgloveClient} = wsProtocol;

const [url, ...stepTexts] = process.argv.slice(2);
const steps = stepTexts.map((text) => JSON.parse(text));
const report = (step, fields) => console.log(JSON.stringify({step, ...fields}));
const b64 = (view) => Buffer.from(view.buffer, view.byteOffset, view.byteLength).toString('base64');
const bytes = (text) => new Uint8Array(Buffer.from(text, 'base64'));

const ws = new WebSocket(url, [process.env.SUBPROTOCOL || FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ws});

// what the server said so far, and waiting for what it will say
const channels = new Map(); // id -> channel
const services = new Map();
const statuses = [];
const waiters = [];
const heard = (event) => {
  for (const waiter of [...waiters]) {
    const result = waiter.test(event);
    if (result !== undefined) {
      waiters.splice(waiters.indexOf(waiter), 1);
      waiter.resolve(result);
    }
  }
};
const next = (test, seconds = 10) => new Promise((resolve, reject) => {
  const waiter = {test, resolve};
  waiters.push(waiter);
  setTimeout(() => reject(new Error(`timed out after ${seconds} s`)), seconds * 1000);
  for (const event of history) { // (what came before the step asked)
    const result = test(event);
    if (result !== undefined) { waiters.splice(waiters.indexOf(waiter), 1); resolve(result); return; }
  }
});
const history = [];
const record = (kind, event) => {
  history.push({kind, event});
  if (history.length > 2000) history.shift();
  heard({kind, event});
};
// (the channel and service maps are updated before anyone waiting hears of the event)
client.on('advertise', (added) => { added.forEach((c) => channels.set(c.id, c)); record('advertise', added); });
client.on('unadvertise', (ids) => { ids.forEach((id) => channels.delete(id)); record('unadvertise', ids); });
client.on('advertiseServices', (added) => { added.forEach((s) => services.set(s.id, s)); record('advertiseServices', added); });
client.on('status', (status) => { statuses.push(status); record('status', status); });
['serverInfo', 'parameterValues', 'serviceCallResponse', 'serviceCallFailure', 'connectionGraphUpdate',
  'fetchAssetResponse', 'message', 'time'].forEach((kind) => client.on(kind, (event) => record(kind, event)));
client.on('close', (event) => { report('closed', {code: event.code, reason: String(event.reason)}); process.exit(0); });
client.on('error', (error) => { report('error', {error: String(error)}); });

const channelOf = (topic) => next(() => [...channels.values()].find((c) => c.topic === topic));
const serviceOf = (name) => next(() => [...services.values()].find((s) => s.name === name));
const kindOf = (kind, test = () => true) => next((e) => (e.kind === kind && test(e.event) ? e.event : undefined));
let ids = 100;

const STEPS = {
  info: async () => ({info: await kindOf('serverInfo'), protocol: ws.protocol}),
  channels: async ({topics}) => {
    for (const topic of topics) await channelOf(topic);
    return {channels: [...channels.values()]};
  },
  services: async ({names}) => {
    for (const name of names) await serviceOf(name);
    return {services: [...services.values()]};
  },
  gone: async ({topic}) => { // no channel of the topic is advertised (any more)
    await next(() => ([...channels.values()].some((c) => c.topic === topic) ? undefined : true));
    return {gone: topic};
  },
  messages: async ({topic, count = 1}) => {
    const channel = await channelOf(topic);
    const sub = client.subscribe(channel.id);
    const got = [];
    await next((e) => {
      if (e.kind === 'message' && e.event.subscriptionId === sub) got.push(e.event);
      return got.length >= count ? true : undefined;
    });
    client.unsubscribe(sub);
    return {messages: got.map((m) => ({data: b64(m.data), timestamp: String(m.timestamp)}))};
  },
  publish: async ({topic, type, encoding = 'ros1', data, count = 1, every = 0.1}) => {
    const channel = client.advertise({topic, encoding, schemaName: type});
    const payload = encoding === 'json' ? new TextEncoder().encode(JSON.stringify(data)) : bytes(data);
    for (let i = 0; i < count; i++) {
      client.sendMessage(channel, payload);
      await new Promise((r) => setTimeout(r, every * 1000));
    }
    return {published: count, channel};
  },
  raw: async ({data, text}) => { // anything, as it is: a binary message (base64) or a text one
    ws.send(text !== undefined ? text : bytes(data));
    return {sent: true};
  },
  status: async ({contains}) => ({status: await kindOf('status', (s) => s.message.includes(contains))}),
  call: async ({service, encoding = 'ros1', data}) => {
    const {id} = await serviceOf(service);
    const callId = ids++;
    const payload = encoding === 'json' ? new TextEncoder().encode(JSON.stringify(data)) : bytes(data || '');
    client.sendServiceCallRequest({serviceId: id, callId, encoding, data: new DataView(payload.buffer)});
    const answer = await Promise.race([
      kindOf('serviceCallResponse', (r) => r.callId === callId).then((r) => ({response: b64(r.data), encoding: r.encoding})),
      kindOf('serviceCallFailure', (f) => f.callId === callId).then((f) => ({failure: f.message})),
    ]);
    return answer;
  },
  'get-params': async ({names}) => {
    const id = `get${ids++}`;
    client.getParameters(names, id);
    return {parameters: (await kindOf('parameterValues', (p) => p.id === id)).parameters};
  },
  'set-params': async ({parameters}) => {
    const id = `set${ids++}`;
    client.setParameters(parameters, id);
    return {parameters: (await kindOf('parameterValues', (p) => p.id === id)).parameters};
  },
  'watch-params': async ({names}) => { client.subscribeParameterUpdates(names); return {watching: names}; },
  'param-update': async ({name}) => ({
    parameters: (await kindOf('parameterValues', (p) => p.id === undefined && p.parameters.some((q) => q.name === name)))
      .parameters,
  }),
  graph: async ({topic}) => {
    client.subscribeConnectionGraph();
    return {graph: await kindOf('connectionGraphUpdate', (g) => !topic || g.publishedTopics.some((t) => t.name === topic))};
  },
  asset: async ({uri}) => {
    const requestId = ids++;
    client.fetchAsset(uri, requestId);
    const answer = await kindOf('fetchAssetResponse', (r) => r.requestId === requestId);
    return answer.status === 0 ? {data: b64(answer.data)} : {error: answer.error};
  },
  time: async () => ({time: String((await kindOf('time')).timestamp)}),
  wait: async ({seconds}) => { await new Promise((r) => setTimeout(r, seconds * 1000)); return {}; },
};

await kindOf('serverInfo');
for (const step of steps) {
  try {
    report(step.do, await STEPS[step.do](step));
  } catch (error) {
    report(step.do, {error: String(error && error.message || error), statuses});
    process.exit(1);
  }
}
client.close();
process.exit(0);
