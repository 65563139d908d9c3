'use strict';
// Node.js client for ism-server (proto/ism/v1/service.proto). The contract is loaded from the
// .proto files at run time, so this client can never drift from the server's proto/.
// Results are plain objects with the proto's fields in lowerCamelCase; enums are their names
// and 64-bit integers are Numbers.
const fs = require('node:fs');
const path = require('node:path');
const os = require('node:os');
const grpc = require('@grpc/grpc-js');
const protoLoader = require('@grpc/proto-loader');

// Repository layout: the contract and grpc.health.v1 in proto/.
const DEFAULT_PROTO_DIRS = [process.env.ISM_PROTO_DIR || path.resolve(__dirname, '../../proto')];

const KINECT = Object.freeze({ fx: 525, fy: 525, cx: 319.5, cy: 239.5, depthScale: 1000 });
const PNG_SIGNATURE = Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);

if (os.endianness() !== 'LE') throw new Error('ism-client packs little-endian floats and needs a little-endian host');

class IsmError extends Error {
  // code: the numeric grpc.status; codeName: its name ("NOT_FOUND"...).
  constructor(code, message) {
    const codeName = Object.keys(grpc.status).find((k) => grpc.status[k] === code) || String(code);
    super(`${codeName}: ${message}`);
    this.name = 'IsmError';
    this.code = code;
    this.codeName = codeName;
    this.details = message;
  }
}

const toIsmError = (e) => (e && typeof e.code === 'number' ? new IsmError(e.code, e.details || e.message) : e);

function loadProtos(protoDirs) {
  const definition = protoLoader.loadSync(['ism/v1/service.proto', 'grpc/health/v1/health.proto'], {
    includeDirs: protoDirs, keepCase: false, longs: Number, enums: String, defaults: true, oneofs: true,
  });
  return grpc.loadPackageDefinition(definition);
}

// Packs Nx3 values (Float32Array/Uint8Array, flat array or array of triples) into a Buffer.
function packRows(rows, ArrayType, what) {
  let flat;
  if (ArrayBuffer.isView(rows)) flat = rows instanceof ArrayType ? rows : ArrayType.from(rows);
  else if (Array.isArray(rows)) flat = ArrayType.from(Array.isArray(rows[0]) ? rows.flat() : rows);
  else throw new TypeError(`${what} must be a typed array or an array of [x, y, z]`);
  if (flat.length % 3 !== 0) throw new RangeError(`${what} has ${flat.length} values, not a multiple of 3`);
  return { bytes: Buffer.from(flat.buffer, flat.byteOffset, flat.byteLength), count: flat.length / 3 };
}

// up: [x, y, z] (or { x, y, z }), the scene's up in its coordinates when known; else the server
// looks for the floor. The server refuses one that is zero or not finite.
function withUp(scene, up) {
  if (up == null) return scene;
  const v = Array.isArray(up) || ArrayBuffer.isView(up) ? Array.from(up) : [up.x, up.y, up.z];
  if (v.length !== 3 || !v.every((c) => typeof c === 'number')) throw new TypeError('up must be three numbers [x, y, z]');
  const [x, y, z] = v;
  return { ...scene, up: { x, y, z } };
}

function cloudScene(points, { rgb, width = 0, height = 0, up } = {}) {
  const xyz = packRows(points, Float32Array, 'points');
  const cloud = { xyz: xyz.bytes, width, height };
  if (rgb != null) {
    const colours = packRows(rgb, Uint8Array, 'rgb');
    if (colours.count !== xyz.count) throw new RangeError(`rgb has ${colours.count} rows but points has ${xyz.count}`);
    cloud.rgb = colours.bytes;
  }
  return withUp({ cloud }, up);
}

// depth: PNG file bytes (Buffer), or { data: Uint16Array (row-major), width, height } raw units.
// up as for cloudScene, in the camera's optical frame (x right, y down, z forward).
function depthScene(depth, intrinsics = KINECT, { up } = {}) {
  const image = { intrinsics: { ...KINECT, ...intrinsics } };
  if (Buffer.isBuffer(depth)) {
    if (!depth.subarray(0, 8).equals(PNG_SIGNATURE)) throw new TypeError('depth Buffer is not a PNG');
    Object.assign(image, { encoding: 'DEPTH_ENCODING_PNG', data: depth });
  } else if (depth && depth.data instanceof Uint16Array) {
    if (depth.data.length !== depth.width * depth.height) {
      throw new RangeError(`depth.data has ${depth.data.length} values for ${depth.width}x${depth.height}`);
    }
    Object.assign(image, {
      encoding: 'DEPTH_ENCODING_RAW_UINT16_LE', width: depth.width, height: depth.height,
      data: Buffer.from(depth.data.buffer, depth.data.byteOffset, depth.data.byteLength),
    });
  } else {
    throw new TypeError('depth must be PNG bytes (Buffer) or { data: Uint16Array, width, height }');
  }
  return withUp({ depth: image }, up);
}

const STRATEGY_ENUMS = {
  codebook: ['CODEBOOK_TYPE', ['global', 'separated']],
  activation: ['ACTIVATION_STRATEGY', ['knn', 'cutoff']],
  weighting: ['VOTE_WEIGHTING', ['categorization', 'localization', 'activation']],
};
const PRESETS = { default: 'RECOGNITION_PRESET_DEFAULT', seed: 'RECOGNITION_PRESET_SEED' };
const POLICIES = { every_frame: 'BACKPRESSURE_POLICY_EVERY_FRAME', latest_frame_wins: 'BACKPRESSURE_POLICY_LATEST_FRAME_WINS' };

function enumValue(kind, name) {
  const [prefix, names] = STRATEGY_ENUMS[kind];
  if (name == null) return `${prefix}_UNSPECIFIED`;
  if (!names.includes(name)) throw new RangeError(`unknown ${kind} '${name}': one of ${names.join(', ')}`);
  return `${prefix}_${name.toUpperCase()}`;
}

// ism.v1.RecognitionOptions from { model, categories, minScore, maxHypotheses, codebook,
// activation, k, cutoff, weighting, returnKeypoints, boxSelection, preset ('default': calibrated
// confidence, one answer per object; 'seed': the seed's pipeline), minConfidence (default preset,
// in [0, 0.99]), oneAnswerPerObject }; unset = the server's and the model's defaults.
function recognitionOptions(o = {}) {
  if (o.preset != null && !PRESETS[o.preset]) {
    throw new RangeError(`unknown preset '${o.preset}': one of ${Object.keys(PRESETS).join(', ')}`);
  }
  const options = {
    model: o.model || '', categories: o.categories || [], maxHypotheses: o.maxHypotheses || 0,
    returnKeypoints: !!o.returnKeypoints,
    strategy: {
      codebook: enumValue('codebook', o.codebook), activation: enumValue('activation', o.activation),
      k: o.k || 0, cutoff: o.cutoff || 0, weighting: enumValue('weighting', o.weighting),
    },
  };
  if (o.minScore != null) options.minScore = o.minScore;
  if (o.boxSelection != null) options.boxSelection = o.boxSelection;
  options.preset = o.preset == null ? 'RECOGNITION_PRESET_UNSPECIFIED' : PRESETS[o.preset];
  if (o.minConfidence != null) options.minConfidence = o.minConfidence;
  if (o.oneAnswerPerObject != null) options.oneAnswerPerObject = o.oneAnswerPerObject;
  return options;
}

function readPem(file, what) {
  let data;
  try {
    data = fs.readFileSync(file);
  } catch (e) {
    throw new Error(`${what} ${file}: ${e.code === 'ENOENT' ? 'no such file' : e.message}`);
  }
  if (!data.includes('-----BEGIN ')) throw new Error(`${what} ${file}: not a PEM file (no '-----BEGIN' line)`);
  return data;
}

// Channel credentials as ism-client's flags: tlsCa (PEM file) trusts that CA instead of the
// system's and implies TLS; tlsCert + tlsKey (PEM files) present a client certificate (mTLS).
// Files are read here, so that a missing one is named now rather than failing a handshake later.
function tlsCredentials({ tlsCa, tlsCert, tlsKey } = {}) {
  if (!tlsCert !== !tlsKey) {
    throw new TypeError('a client certificate needs its key and a key its certificate: give both tlsCert and tlsKey, or neither');
  }
  return grpc.credentials.createSsl(tlsCa ? readPem(tlsCa, 'TLS CA') : null, tlsKey ? readPem(tlsKey, 'TLS key') : null,
    tlsCert ? readPem(tlsCert, 'TLS certificate') : null);
}

// Per-call metadata rather than call credentials: gRPC sends those only over TLS, and a token
// over plain text is legitimate on loopback or behind a TLS-terminating proxy (as ism-client).
function tokenMetadata(token) {
  const metadata = new grpc.Metadata();
  if (token == null || token === '') return metadata;
  const trimmed = String(token).trim(); // as the server trims its token files
  if (!/^[\x21-\x7e]+$/.test(trimmed)) {
    throw new TypeError("token must be printable ASCII without blanks (it travels as 'authorization: Bearer TOKEN')");
  }
  metadata.set('authorization', `Bearer ${trimmed}`);
  return metadata;
}

class Client {
  // address: any gRPC target ("host:port", "ipv4:a:p1,b:p2", "dns:///svc:50051").
  // timeoutMs: each unary call's deadline. serviceConfig: an object such as
  // { loadBalancingConfig: [{ round_robin: {} }], methodConfig: [...] }.
  // Security: tls (true: TLS trusting the system's CAs), tlsCa, tlsCert + tlsKey (PEM file
  // paths; any of them implies TLS), tlsServerName (the name the server certificate is checked
  // against; default: the host of address), token (sent as 'authorization: Bearer TOKEN').
  constructor(address, {
    timeoutMs = 30000, maxMessageMb = 64, serviceConfig, protoDirs = DEFAULT_PROTO_DIRS,
    tls = false, tlsCa, tlsCert, tlsKey, tlsServerName, token,
  } = {}) {
    const pkg = loadProtos(protoDirs);
    const options = {
      'grpc.max_receive_message_length': maxMessageMb << 20,
      'grpc.max_send_message_length': maxMessageMb << 20,
    };
    if (serviceConfig) options['grpc.service_config'] = JSON.stringify(serviceConfig);
    let credentials = grpc.credentials.createInsecure();
    if (tls || tlsCa || tlsCert || tlsKey || tlsServerName) {
      credentials = tlsCredentials({ tlsCa, tlsCert, tlsKey });
      if (tlsServerName) options['grpc.ssl_target_name_override'] = tlsServerName;
    }
    this.address = address;
    this.timeoutMs = timeoutMs;
    this.metadata = tokenMetadata(token);
    this.stub = new pkg.ism.v1.FurnitureRecognizer(address, credentials, options);
    this.healthStub = new pkg.grpc.health.v1.Health(address, credentials, options);
  }

  close() {
    this.stub.close();
    this.healthStub.close();
  }

  unary(stub, method, request, timeoutMs) {
    const deadline = new Date(Date.now() + (timeoutMs ?? this.timeoutMs));
    return new Promise((resolve, reject) => {
      stub[method](request, this.metadata.clone(), { deadline },
        (err, response) => (err ? reject(toIsmError(err)) : resolve(response)));
    });
  }

  // scene: an ism.v1.Scene object (see cloudScene/depthScene). Resolves to a RecognitionResult.
  async recognize(scene, { requestId = '', timeoutMs, ...options } = {}) {
    const request = { requestId, scene, options: recognitionOptions(options) };
    return (await this.unary(this.stub, 'recognize', request, timeoutMs)).result;
  }

  // points: Nx3 metres; options: rgb, width, height (organized clouds), up, requestId, timeoutMs
  // and those of recognitionOptions. The result's hypotheses come most confident first, with
  // confidence and alternatives; result.gravity is the up their boxes stand along.
  async recognizeCloud(points, { rgb, width, height, up, ...options } = {}) {
    return this.recognize(cloudScene(points, { rgb, width, height, up }), options);
  }

  async recognizeDepth(depth, intrinsics = KINECT, { up, ...options } = {}) {
    return this.recognize(depthScene(depth, intrinsics, { up }), options);
  }

  // frames: an (async) iterable of { points, rgb } or { depth, intrinsics }, with optional
  // frameId (default: 0, 1, 2...), timestampUs and up. Yields FrameResults in frame order.
  // policy: 'every_frame' (flow control slows the sender) or 'latest_frame_wins'.
  async* streamFrames(frames, { policy = 'every_frame', ...options } = {}) {
    if (!POLICIES[policy]) throw new RangeError(`unknown policy '${policy}': one of ${Object.keys(POLICIES).join(', ')}`);
    const call = this.stub.streamFrames(this.metadata.clone());
    const settings = { policy: POLICIES[policy], options: recognitionOptions(options) };
    let sendError = null;
    const send = (async () => {
      let index = 0;
      for await (const frame of frames) {
        const scene = frame.depth != null ? depthScene(frame.depth, frame.intrinsics, frame) : cloudScene(frame.points, frame);
        const request = { frameId: frame.frameId ?? index, timestampUs: frame.timestampUs || 0, scene };
        if (index === 0) request.settings = settings;
        index += 1;
        // write() returns false when gRPC's buffer is full: wait, so that a slow server slows us.
        if (!call.write(request)) await new Promise((resolve) => call.once('drain', resolve));
      }
      call.end();
    })().catch((e) => {
      sendError = e;
      call.cancel();
    });
    try {
      for await (const result of call) yield result;
    } catch (e) {
      throw sendError || toIsmError(e);
    } finally {
      call.cancel();
      await send;
    }
    if (sendError) throw sendError;
  }

  async listModels({ timeoutMs } = {}) {
    return (await this.unary(this.stub, 'listModels', {}, timeoutMs)).models;
  }

  getModel(name, { timeoutMs } = {}) {
    return this.unary(this.stub, 'getModel', { name }, timeoutMs);
  }

  // Resolves to the grpc.health.v1 status name: 'SERVING', 'NOT_SERVING', ...
  async health(service = '', { timeoutMs } = {}) {
    return (await this.unary(this.healthStub, 'check', { service }, timeoutMs)).status;
  }
}

const connect = (address, options) => new Client(address, options);

module.exports = { Client, IsmError, KINECT, cloudScene, connect, depthScene, recognitionOptions, tlsCredentials };
