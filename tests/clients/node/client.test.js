'use strict';
// The Node client (client/node) against a real ism-server on 127.0.0.1; run by ctest with
// ISM_SERVER_BIN and ISM_TEST_MODEL_DIR set; the security tests make their certificates with openssl.
const test = require('node:test');
const assert = require('node:assert/strict');
const zlib = require('node:zlib');
const path = require('node:path');
const { connect, IsmError } = require(path.resolve(__dirname, '../../../client/node'));
const { startServer } = require('./server');
const { USER_TOKEN, makePki } = require('./certs');

const SMALL = { fx: 131.25, fy: 131.25, cx: 79.5, cy: 59.5, depthScale: 1000 };

// A 1.6 m floor with a 0.8 x 0.5 x 0.75 m box on it, 2 cm spacing, as a flat Float32Array.
function boxOnFloor() {
  const pts = [];
  for (let x = -0.8; x < 0.8; x += 0.02) for (let y = -0.8; y < 0.8; y += 0.02) pts.push(x, y, 0);
  for (let x = -0.4; x < 0.4; x += 0.02) for (let y = -0.25; y < 0.25; y += 0.02) pts.push(x, y, 0.75);
  for (let z = 0; z < 0.75; z += 0.02) {
    for (let y = -0.25; y < 0.25; y += 0.02) pts.push(-0.4, y, z, 0.4, y, z);
    for (let x = -0.4; x < 0.4; x += 0.02) pts.push(x, -0.25, z, x, 0.25, z);
  }
  return Float32Array.from(pts);
}

// 160x120 millimetres: a wall at 2.5 m, a box face at 1.6 m, an invalid top border.
function depthOfBox(width = 160, height = 120) {
  const data = new Uint16Array(width * height).fill(2500);
  for (let r = height / 3; r < (2 * height) / 3; r++) data.fill(1600, r * width + width / 3, r * width + (2 * width) / 3);
  data.fill(0, 0, 4 * width);
  return { data, width, height };
}

function crc32(buf) {
  let c = ~0;
  for (const byte of buf) {
    c ^= byte;
    for (let k = 0; k < 8; k++) c = (c >>> 1) ^ (0xedb88320 & -(c & 1));
  }
  return ~c >>> 0;
}

function png16({ data, width, height }) {
  const chunk = (type, body) => {
    const head = Buffer.alloc(4);
    head.writeUInt32BE(body.length);
    const tail = Buffer.alloc(4);
    tail.writeUInt32BE(crc32(Buffer.concat([Buffer.from(type), body])));
    return Buffer.concat([head, Buffer.from(type), body, tail]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr.set([16, 0, 0, 0, 0], 8);
  const rows = Buffer.alloc(height * (1 + 2 * width));
  for (let r = 0; r < height; r++) {
    for (let c = 0; c < width; c++) rows.writeUInt16BE(data[r * width + c], r * (1 + 2 * width) + 1 + 2 * c);
  }
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(rows)), chunk('IEND', Buffer.alloc(0))]);
}

test('client against a real ism-server', async (t) => {
  const server = await startServer();
  const client = connect(server.address, { timeoutMs: 60000 });
  t.after(async () => { client.close(); await server.stop(); });
  const models = await client.listModels();
  assert.ok(models.length > 0, `no model loaded:\n${server.log()}`);
  const model = models[0];
  const points = boxOnFloor();
  const depth = depthOfBox();
  const validDepthPixels = depth.data.filter((d) => d > 0).length;

  const assertValidResult = (result, inputPoints) => {
    assert.equal(result.modelName, model.name);
    assert.equal(result.modelVersion, model.version);
    if (inputPoints !== undefined) assert.equal(result.inputPoints, inputPoints);
    assert.ok(result.totalMs > 0);
    assert.ok(result.timings.length > 0);
    const categories = new Set(model.categories.map((c) => c.name));
    for (const h of result.hypotheses) {
      assert.ok(categories.has(h.category), h.category);
      assert.ok(h.score >= h.threshold);
    }
  };

  await t.test('health is SERVING', async () => assert.equal(await client.health(), 'SERVING'));

  await t.test('getModel agrees with listModels; unknown names are NOT_FOUND', async () => {
    const info = await client.getModel(model.name);
    assert.equal(info.version, model.version);
    assert.ok(info.categories.length > 0);
    await assert.rejects(client.getModel('no-such-model'), (e) => e instanceof IsmError && e.codeName === 'NOT_FOUND');
  });

  await t.test('recognizeCloud from a Float32Array and from triples', async () => {
    assertValidResult(await client.recognizeCloud(points, { requestId: 'node-typed' }), points.length / 3);
    const triples = [];
    for (let i = 0; i < points.length; i += 12) triples.push([points[i], points[i + 1], points[i + 2]]);
    const rgb = new Uint8Array(triples.length * 3).fill(200);
    assertValidResult(await client.recognizeCloud(triples, { rgb }), triples.length);
  });

  await t.test('recognizeDepth: raw and PNG encodings give the same result', async () => {
    const raw = await client.recognizeDepth(depth, SMALL);
    const png = await client.recognizeDepth(png16(depth), SMALL);
    assertValidResult(raw, validDepthPixels);
    assert.deepEqual([png.inputPoints, png.keypoints, png.hypotheses.length],
      [raw.inputPoints, raw.keypoints, raw.hypotheses.length]);
  });

  await t.test('server errors carry their gRPC code', async () => {
    await assert.rejects(client.recognizeCloud(points, { model: 'no-such-model' }), (e) => e.codeName === 'NOT_FOUND');
    await assert.rejects(client.recognizeDepth(depth, { fx: 0, fy: 0 }),
      (e) => e.codeName === 'INVALID_ARGUMENT' && /fx/.test(e.details));
  });

  await t.test('bad input is refused before sending', async () => {
    await assert.rejects(client.recognizeCloud(new Float32Array(10)), /multiple of 3/);
    await assert.rejects(client.recognizeDepth(Buffer.from('not a png'), SMALL), /not a PNG/);
    await assert.rejects(client.recognizeCloud(points, { weighting: 'heaviest' }), /unknown weighting/);
    await assert.rejects(client.recognizeCloud(points, { preset: 'fancy' }), /unknown preset/);
    await assert.rejects(client.recognizeCloud(points, { up: [0, 1] }), /up must be three numbers/);
  });

  await t.test('default preset: confidences in [0, 1], best first; the given up is reported back', async () => {
    const result = await client.recognizeCloud(points, { up: [0, 0, 2], minConfidence: 0.01 });
    assertValidResult(result, points.length / 3);
    result.hypotheses.forEach((h, i) => {
      assert.ok(h.confidence >= 0.01 && h.confidence <= 1, `confidence ${h.confidence}`);
      if (i > 0) assert.ok(h.confidence <= result.hypotheses[i - 1].confidence, 'not most confident first');
      for (const a of h.alternatives) assert.ok(a.category !== h.category && a.confidence <= h.confidence);
      assert.equal(typeof h.uprightBox, 'boolean');
    });
    // A model trained before the gravity stage (no front-end gravity parameters) reports none.
    if (model.frontEnd.gravity) {
      assert.equal(result.gravity.source, 'UP_SOURCE_GIVEN');
      assert.deepEqual([result.gravity.up.x, result.gravity.up.y, result.gravity.up.z], [0, 0, 1]);
    } else {
      assert.equal(result.gravity, null);
    }
  });

  await t.test('seed preset: ranked by score over threshold, nothing merged', async () => {
    const result = await client.recognizeCloud(points, { preset: 'seed', minScore: 0, boxSelection: false, maxHypotheses: 6 });
    assert.ok(result.hypotheses.length > 0);
    const relative = (h) => (h.threshold > 0 ? h.score / h.threshold : h.score);
    result.hypotheses.forEach((h, i) => {
      if (i > 0) assert.ok(relative(h) <= relative(result.hypotheses[i - 1]), 'not ranked by score / threshold');
      assert.deepEqual(h.alternatives, []);
    });
  });

  await t.test('bad up and minConfidence are INVALID_ARGUMENT naming the field', async () => {
    const invalid = (pattern) => (e) => e instanceof IsmError && e.codeName === 'INVALID_ARGUMENT' && pattern.test(e.details);
    await assert.rejects(client.recognizeCloud(points, { up: [0, 0, 0] }), invalid(/^scene\.up = \(0, 0, 0\)/));
    await assert.rejects(client.recognizeCloud(points, { up: [NaN, 0, 1] }), invalid(/^scene\.up/));
    await assert.rejects(client.recognizeCloud(points, { minConfidence: 1.5 }), invalid(/options\.min_confidence = 1\.5/));
    const results = [];
    for await (const r of client.streamFrames([{ points, up: [0, 0, 0] }, { points, up: [0, 0, 1] }])) results.push(r);
    assert.deepEqual(results.map((r) => r.outcome), ['error', 'result']);
    assert.match(results[0].error.message, /scene\.up/);
  });

  await t.test('streamFrames answers every frame in order and isolates a bad one', async () => {
    const half = Math.floor(points.length / 6) * 3;
    async function* frames() {
      yield { points: points.subarray(0, half), timestampUs: 1000 };
      yield { depth, intrinsics: { fx: 0, fy: 0 } };
      yield { depth: png16(depth), intrinsics: SMALL, frameId: 42 };
    }
    const results = [];
    for await (const r of client.streamFrames(frames(), { policy: 'every_frame' })) results.push(r);
    assert.deepEqual(results.map((r) => r.frameId), [0, 1, 42]);
    assert.deepEqual(results.map((r) => r.outcome), ['result', 'error', 'result']);
    assert.equal(results[0].timestampUs, 1000);
    assertValidResult(results[0].result, half / 3);
    assert.equal(results[1].error.code, 3);
    assertValidResult(results[2].result, validDepthPixels);
    await assert.rejects(async () => { for await (const r of client.streamFrames(frames(), { policy: 'fastest' })) void r; },
      /unknown policy/);
    async function* badSecondFrame() {
      yield { points: points.subarray(0, half) };
      yield { points: new Float32Array(4) };
    }
    await assert.rejects(async () => { for await (const r of client.streamFrames(badSecondFrame())) void r; },
      /multiple of 3/);
  });
});

test('client against a real ism-server with TLS and tokens', async (t) => {
  const pki = makePki();
  const server = await startServer({ args: pki.serverFlags() });
  const mtls = await startServer({ args: pki.serverFlags('ca') });
  const clients = [];
  const open = (srv, options) => {
    const client = connect(srv.address, { timeoutMs: 30000, ...options });
    clients.push(client);
    return client;
  };
  t.after(async () => {
    for (const client of clients) client.close();
    await Promise.all([server.stop(), mtls.stop()]);
    pki.remove();
  });
  const tlsCa = pki.file('ca.crt');
  const points = boxOnFloor();
  const rejectsWith = (promise, codeName, pattern = /./) => assert.rejects(promise,
    (e) => e instanceof IsmError && e.codeName === codeName && pattern.test(e.details));

  await t.test('no token: UNAUTHENTICATED on every RPC but health', async () => {
    const client = open(server, { tlsCa });
    assert.equal(await client.health(), 'SERVING');
    await rejectsWith(client.listModels(), 'UNAUTHENTICATED', /authorization: Bearer/);
    await rejectsWith(client.recognizeCloud(points), 'UNAUTHENTICATED');
    await rejectsWith((async () => { for await (const r of client.streamFrames([{ points }])) void r; })(), 'UNAUTHENTICATED');
  });

  await t.test('wrong token: UNAUTHENTICATED', async () => {
    await rejectsWith(open(server, { tlsCa, token: 'not-a-token-of-this-server' }).listModels(), 'UNAUTHENTICATED', /not accepted/);
  });

  await t.test('right token: results from unary and streaming RPCs', async () => {
    const client = open(server, { tlsCa, token: `${USER_TOKEN}\n` });
    const models = await client.listModels();
    assert.ok(models.length > 0, server.log());
    const result = await client.recognizeCloud(points);
    assert.equal(result.inputPoints, points.length / 3);
    assert.equal(result.modelName, models[0].name);
    const frames = [];
    for await (const r of client.streamFrames([{ points, frameId: 5 }])) frames.push([r.frameId, r.outcome]);
    assert.deepEqual(frames, [[5, 'result']]);
  });

  await t.test('wrong CA or plain text: the handshake fails', async () => {
    const rogue = open(server, { tlsCa: pki.file('rogue-ca.crt'), token: USER_TOKEN });
    await rejectsWith(rogue.health(), 'UNAVAILABLE', /certificate/);
    // A later call on the same channel may fail during reconnect backoff, without the reason.
    await rejectsWith(rogue.listModels(), 'UNAVAILABLE');
    await rejectsWith(open(server, { token: USER_TOKEN }).health(), 'UNAVAILABLE');
  });

  await t.test('mTLS: only a client certificate from the client CA is let in', async () => {
    const accepted = open(mtls, { tlsCa, tlsCert: pki.file('client.crt'), tlsKey: pki.file('client.key'), token: USER_TOKEN });
    assert.ok((await accepted.listModels()).length > 0);
    await rejectsWith(open(mtls, { tlsCa, token: USER_TOKEN }).health(), 'UNAVAILABLE');
    const rogue = open(mtls, { tlsCa, tlsCert: pki.file('rogue-client.crt'), tlsKey: pki.file('rogue-client.key'), token: USER_TOKEN });
    await rejectsWith(rogue.health(), 'UNAVAILABLE');
  });

  await t.test('bad security options are refused before connecting', () => {
    assert.throws(() => connect(server.address, { tlsCert: pki.file('client.crt') }), /give both tlsCert and tlsKey/);
    assert.throws(() => connect(server.address, { tlsCa: pki.file('missing.crt') }), /TLS CA .*missing\.crt: no such file/);
    assert.throws(() => connect(server.address, { tlsCa: pki.file('tokens') }), /tokens: not a PEM file/);
    assert.throws(() => connect(server.address, { token: 'two words' }), /printable ASCII/);
  });
});
