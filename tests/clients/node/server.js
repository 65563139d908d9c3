'use strict';
// Starts a real ism-server on 127.0.0.1 for the Node client tests. The server picks its own
// gRPC port (--listen 127.0.0.1:0) and names it in its "listening on ... (port N)" log line.
const { spawn } = require('node:child_process');

// args: extra ism-server flags (TLS, token files).
function startServer({
  bin = process.env.ISM_SERVER_BIN, modelDir = process.env.ISM_TEST_MODEL_DIR, timeoutMs = 30000, args = [],
} = {}) {
  if (!bin) throw new Error('ISM_SERVER_BIN is not set (ctest sets it to the ism-server binary)');
  const child = spawn(bin, ['--listen', '127.0.0.1:0', '--metrics-listen', '', '--models', modelDir, '--threads', '2', ...args],
    { stdio: ['ignore', 'pipe', 'pipe'] });
  let log = '';
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => { child.kill('SIGKILL'); reject(new Error(`ism-server did not start:\n${log}`)); }, timeoutMs);
    const onData = (chunk) => {
      log += chunk;
      const match = /listening on \S+ \(port (\d+)[,)]/.exec(log);
      if (match && timer) {
        clearTimeout(timer);
        resolve({
          address: `127.0.0.1:${match[1]}`,
          log: () => log,
          stop: () => new Promise((done) => { child.once('exit', done); child.kill('SIGTERM'); }),
        });
      }
    };
    child.stdout.on('data', onData);
    child.stderr.on('data', onData);
    child.once('exit', (code) => { clearTimeout(timer); reject(new Error(`ism-server exited with ${code}:\n${log}`)); });
  });
}

module.exports = { startServer };
