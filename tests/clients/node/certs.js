'use strict';
// A throwaway PKI for the Node client's security tests, made with the openssl command as
// tests/clients/certs.py and tests/service/security_test.cc do: a CA and an unrelated one, a
// server certificate for 127.0.0.1, client certificates from each CA, and a user token file.
const { execFileSync } = require('node:child_process');
const fs = require('node:fs');
const os = require('node:os');
const path = require('node:path');

const USER_TOKEN = 'user-token-7e2a91d04c6b3f85';

function openssl(...args) {
  try {
    execFileSync('openssl', args, { stdio: 'pipe', timeout: 60000 });
  } catch (e) {
    throw new Error(`openssl ${args.join(' ')} failed:\n${e.stderr || e.message}`);
  }
}

function makePki() {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'ism-node-pki-'));
  const file = (name) => path.join(dir, name);
  const newKey = ['-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:prime256v1', '-nodes'];
  for (const ca of ['ca', 'rogue-ca']) {
    openssl('req', '-x509', ...newKey, '-days', '1', '-subj', `/CN=${ca}`, '-keyout', file(`${ca}.key`), '-out', file(`${ca}.crt`));
  }
  const certificate = (name, ca, extensions) => {
    fs.writeFileSync(file(`${name}.ext`), `${extensions}\n`);
    openssl('req', ...newKey, '-subj', `/CN=${name}`, '-keyout', file(`${name}.key`), '-out', file(`${name}.csr`));
    openssl('x509', '-req', '-days', '1', '-in', file(`${name}.csr`), '-CA', file(`${ca}.crt`), '-CAkey', file(`${ca}.key`),
      '-CAcreateserial', '-extfile', file(`${name}.ext`), '-out', file(`${name}.crt`));
  };
  certificate('server', 'ca', 'subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth');
  certificate('client', 'ca', 'extendedKeyUsage=clientAuth');
  certificate('rogue-client', 'rogue-ca', 'extendedKeyUsage=clientAuth');
  fs.writeFileSync(file('tokens'), `${USER_TOKEN}\n`, { mode: 0o600 });
  return {
    dir,
    file,
    // ism-server flags: TLS, the token file and, with clientCa, mTLS.
    serverFlags: (clientCa) => ['--tls-cert', file('server.crt'), '--tls-key', file('server.key'), '--token-file', file('tokens'),
      ...(clientCa ? ['--tls-client-ca', file(`${clientCa}.crt`)] : [])],
    remove: () => fs.rmSync(dir, { recursive: true, force: true }),
  };
}

module.exports = { USER_TOKEN, makePki };
