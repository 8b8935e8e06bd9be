#!/usr/bin/env node
// Serves the viewer and one model locally:
//   node web-viewer/serve.mjs MODEL.glb|MODEL.gltf [--port N] [--host 127.0.0.1] [--no-compress]
// prints http://127.0.0.1:PORT/?model=model/NAME and serves until interrupted.
//   /            the viewer (this folder: index.html, the ES modules, node_modules/three)
//   /model/...   the model's folder (so a .gltf finds its .bin files)
// Node's http only: GET and HEAD, single Range requests (206, 416), MIME types for the viewer and
// glTF files, nothing outside the two folders. The viewer's text and WebAssembly files (three.js
// is 2.1 MB as npm ships it) are sent brotli- or gzip-compressed when the browser accepts it, as
// any web server or static host does (compressed once per file and kept; --no-compress: as they
// are); model files are sent as they are (Draco inside; Range requests need their bytes). Cache-Control: no-cache without validators, so
// every load fetches again (not no-store: with it Chromium aborts its code-cache write of the
// Draco .wasm and reports that fetch as failed).
// Run `npm ci` in web-viewer/ once first (three.js and its Draco decoder come from node_modules).
import { createServer } from 'node:http';
import { brotliCompress, constants as zlibConstants, gzip } from 'node:zlib';
import { promisify } from 'node:util';
import { createReadStream, existsSync, statSync } from 'node:fs';
import { readFile } from 'node:fs/promises';
import { basename, dirname, extname, join, relative, resolve, sep } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const kHere = dirname(fileURLToPath(import.meta.url));

export const kMimeTypes = {
    '.html': 'text/html; charset=utf-8',
    '.js': 'text/javascript; charset=utf-8',
    '.mjs': 'text/javascript; charset=utf-8',
    '.css': 'text/css; charset=utf-8',
    '.json': 'application/json',
    '.map': 'application/json',
    '.wasm': 'application/wasm',
    '.glb': 'model/gltf-binary',
    '.gltf': 'model/gltf+json',
    '.bin': 'application/octet-stream',
    '.png': 'image/png',
    '.jpg': 'image/jpeg',
    '.svg': 'image/svg+xml',
    '.txt': 'text/plain; charset=utf-8',
    '.md': 'text/markdown; charset=utf-8',
};

/// Extensions of the viewer's files sent compressed (text and WebAssembly).
const kCompressible = new Set(['.html', '.js', '.mjs', '.css', '.json', '.map', '.wasm', '.svg', '.txt', '.md']);

/// The encoding to answer an Accept-Encoding header with: 'br', 'gzip' or null (q=0 refuses).
export function pickEncoding(header) {
    if (!header) return null;
    const accepted = new Map();
    for (const part of header.split(',')) {
        const [name, ...params] = part.trim().toLowerCase().split(';');
        const q = params.map((x) => /^\s*q=([0-9.]+)\s*$/.exec(x)).find(Boolean);
        accepted.set(name, q ? Number(q[1]) : 1);
    }
    for (const encoding of ['br', 'gzip']) if ((accepted.get(encoding) ?? 0) > 0) return encoding;
    return null;
}

const brotli = promisify(brotliCompress);
const gzipAsync = promisify(gzip);

/// Compressed bodies of the viewer's files, one per file, version (mtime, size) and encoding:
/// brotli quality 9 (quality 11, what precompressing hosts use, takes 15 s on three.js here and
/// saves 10 % more), gzip level 9.
class CompressedFiles {
    constructor() {
        this.cache = new Map();
    }

    get(file, encoding) {
        const stat = statSync(file);
        const key = `${encoding}:${file}:${stat.mtimeMs}:${stat.size}`;
        if (!this.cache.has(key)) {
            const body = readFile(file).then((bytes) =>
                encoding === 'br'
                    ? brotli(bytes, {
                          params: {
                              [zlibConstants.BROTLI_PARAM_QUALITY]: 9,
                              [zlibConstants.BROTLI_PARAM_SIZE_HINT]: bytes.length,
                          },
                      })
                    : gzipAsync(bytes, { level: 9 }),
            );
            this.cache.set(key, body);
            body.catch(() => this.cache.delete(key));
        }
        return this.cache.get(key);
    }
}

/// The file under root for a URL path, or null when it leaves root or does not exist.
function fileUnder(root, urlPath) {
    let decoded;
    try {
        decoded = decodeURIComponent(urlPath);
    } catch {
        return null;
    }
    if (decoded.includes('\0')) return null;
    const file = resolve(root, `.${decoded.startsWith('/') ? decoded : `/${decoded}`}`);
    const rel = relative(root, file);
    if (rel.startsWith('..') || rel.split(sep).includes('..') || resolve(root, rel) !== file) return null;
    if (!existsSync(file)) return null;
    const stat = statSync(file);
    if (stat.isDirectory()) {
        const index = join(file, 'index.html');
        return existsSync(index) ? { file: index, size: statSync(index).size } : null;
    }
    return stat.isFile() ? { file, size: stat.size } : null;
}

/// Parses a Range header for a file of `size` bytes: null (no or unsupported range: send all),
/// 'invalid' (416), or { start, end } inclusive.
export function parseRange(header, size) {
    if (!header) return null;
    const match = /^bytes=(\d*)-(\d*)$/.exec(header.trim());
    if (!match) return null; // multiple ranges or other units: answer with the whole file
    const [, a, b] = match;
    let start;
    let end;
    if (a === '' && b === '') return 'invalid';
    if (a === '') {
        const suffix = Number(b);
        if (suffix === 0) return 'invalid';
        start = Math.max(0, size - suffix);
        end = size - 1;
    } else {
        start = Number(a);
        end = b === '' ? size - 1 : Math.min(Number(b), size - 1);
    }
    if (start >= size || start > end) return 'invalid';
    return { start, end };
}

/// Starts the server. model: path of a .glb or .gltf (its folder is served under /model/).
/// Returns { server, port, url, close() }. log: function for one line per request (optional).
/// viewerMaxAge: seconds the viewer's own files (everything outside /model/) may be cached
/// (default 0: no-cache, every load fetches them again; a benchmark's returning visitor sets it).
/// compress: send the viewer's text and WebAssembly files brotli/gzip-compressed to browsers that
/// accept it (default true; model files never).
export function startServer({
    model,
    port = 8347,
    host = '127.0.0.1',
    log = null,
    viewerRoot = kHere,
    viewerMaxAge = 0,
    compress = true,
} = {}) {
    const compressed = new CompressedFiles();
    const modelFile = model ? resolve(model) : null;
    const modelRoot = modelFile ? dirname(modelFile) : null;
    const server = createServer((request, response) => {
        const url = new URL(request.url, 'http://localhost');
        const send = (status, text) => {
            response.writeHead(status, { 'Content-Type': 'text/plain; charset=utf-8', 'Cache-Control': 'no-store' });
            response.end(request.method === 'HEAD' ? undefined : text);
            log?.(`${status} ${request.method} ${url.pathname}`);
        };
        if (request.method !== 'GET' && request.method !== 'HEAD') {
            send(405, 'method not allowed\n');
            return;
        }
        let found = null;
        const isModel = url.pathname.startsWith('/model/');
        if (isModel) {
            found = modelRoot ? fileUnder(modelRoot, url.pathname.slice('/model'.length)) : null;
        } else {
            found = fileUnder(viewerRoot, url.pathname);
        }
        if (found === null) {
            send(404, 'not found\n');
            return;
        }
        const headers = {
            'Content-Type': kMimeTypes[extname(found.file).toLowerCase()] ?? 'application/octet-stream',
            'Accept-Ranges': 'bytes',
            'Cache-Control': !isModel && viewerMaxAge > 0 ? `max-age=${viewerMaxAge}` : 'no-cache',
        };
        const encoding =
            compress && !isModel && kCompressible.has(extname(found.file).toLowerCase())
                ? pickEncoding(request.headers['accept-encoding'])
                : null;
        if (encoding !== null) {
            // the whole file, compressed (a Range request on these gets the whole body: 200)
            headers['Content-Encoding'] = encoding;
            headers.Vary = 'Accept-Encoding';
            delete headers['Accept-Ranges'];
            compressed.get(found.file, encoding).then(
                (body) => {
                    headers['Content-Length'] = String(body.length);
                    response.writeHead(200, headers);
                    response.end(request.method === 'HEAD' ? undefined : body);
                    log?.(`200 ${request.method} ${url.pathname} (${encoding} ${body.length} of ${found.size} bytes)`);
                },
                () => response.destroy(),
            );
            return;
        }
        const range = parseRange(request.headers.range, found.size);
        if (range === 'invalid') {
            response.writeHead(416, { ...headers, 'Content-Range': `bytes */${found.size}` });
            response.end();
            log?.(`416 ${request.method} ${url.pathname} ${request.headers.range}`);
            return;
        }
        let status = 200;
        let start = 0;
        let end = found.size - 1;
        if (range !== null) {
            status = 206;
            ({ start, end } = range);
            headers['Content-Range'] = `bytes ${start}-${end}/${found.size}`;
        }
        headers['Content-Length'] = String(Math.max(0, end - start + 1));
        response.writeHead(status, headers);
        log?.(`${status} ${request.method} ${url.pathname}${range ? ` ${start}-${end}` : ''}`);
        if (request.method === 'HEAD' || found.size === 0) {
            response.end();
            return;
        }
        const stream = createReadStream(found.file, { start, end });
        stream.on('error', () => response.destroy());
        stream.pipe(response);
    });
    return new Promise((resolvePromise, reject) => {
        server.once('error', reject);
        server.listen(port, host, () => {
            const actual = server.address().port;
            const modelPath = modelFile ? `?model=model/${encodeURIComponent(basename(modelFile))}` : '';
            const url = `http://${host}:${actual}/${modelPath}`;
            resolvePromise({
                server,
                port: actual,
                url,
                close: () =>
                    new Promise((r) => {
                        server.closeAllConnections?.();
                        server.close(() => r());
                    }),
            });
        });
    });
}

/// Why a model path cannot be served, or null.
export function modelProblem(model) {
    let stat;
    try {
        stat = statSync(model);
    } catch (error) {
        if (error.code === 'ENOENT')
            return `${model}: no such file (expected a .glb or .gltf written by \`strata build\`)`;
        if (error.code === 'EACCES') return `${model}: permission denied`;
        return `${model}: cannot read it (${error.code ?? error.message})`;
    }
    if (stat.isDirectory())
        return `${model}: a folder, expected a .glb or .gltf file (e.g. ${join(model, 'model.glb')})`;
    if (!stat.isFile()) return `${model}: not a regular file, expected a .glb or .gltf file`;
    if (!/\.(glb|gltf)$/i.test(model)) return `${model}: not a .glb or .gltf file (by its extension)`;
    return null;
}

/// A clear message for a server that could not listen.
export function listenProblem(error, host, port) {
    switch (error?.code) {
        case 'EADDRINUSE':
            return `port ${port} on ${host} is already in use: stop the other server or pass --port N (--port 0 picks a free port)`;
        case 'EACCES':
            return `no permission to listen on port ${port} of ${host}: pass --port N with N >= 1024`;
        case 'EADDRNOTAVAIL':
        case 'ENOTFOUND':
            return `cannot listen on ${host}: not an address of this machine (--host)`;
        default:
            return `cannot listen on ${host}:${port}: ${error?.message ?? error}`;
    }
}

/// Prints `serve.mjs: error: MESSAGE` and exits with 2 (bad input or usage, as strata does).
function fail(message) {
    console.error(`serve.mjs: error: ${message}`);
    process.exit(2);
}

function usage(message) {
    if (message) console.error(`serve.mjs: ${message}`);
    console.error(
        'usage: node web-viewer/serve.mjs MODEL.glb|MODEL.gltf [--port N] [--host ADDRESS] [--verbose] [--no-compress]',
    );
    process.exit(2);
}

async function main(args) {
    let model = null;
    let port = 8347;
    let host = '127.0.0.1';
    let verbose = false;
    let compress = true;
    for (let i = 0; i < args.length; ++i) {
        const arg = args[i];
        if (arg === '--port') {
            port = Number(args[++i]);
            if (!Number.isInteger(port) || port < 0 || port > 65535) usage(`bad port ${args[i]}`);
        } else if (arg === '--host') {
            host = args[++i];
            if (!host) usage('--host needs an address');
        } else if (arg === '--verbose') {
            verbose = true;
        } else if (arg === '--no-compress') {
            compress = false;
        } else if (arg === '-h' || arg === '--help') {
            usage();
        } else if (arg.startsWith('-')) {
            usage(`unknown option ${arg}`);
        } else if (model === null) {
            model = arg;
        } else {
            usage('one model only');
        }
    }
    if (model === null) usage('no model given');
    const problem = modelProblem(model);
    if (problem !== null) fail(problem);
    if (!existsSync(join(kHere, 'node_modules', 'three', 'build', 'three.module.js'))) {
        fail(`three.js is missing in ${kHere}/node_modules: run \`npm ci\` there`);
    }
    let url;
    try {
        ({ url } = await startServer({
            model,
            port,
            host,
            compress,
            log: verbose ? (line) => console.log(line) : null,
        }));
    } catch (error) {
        fail(listenProblem(error, host, port));
    }
    console.log(`strata viewer: ${url}`);
    console.log('(Ctrl-C stops the server)');
}

if (process.argv[1] && import.meta.url === pathToFileURL(resolve(process.argv[1])).href) {
    await main(process.argv.slice(2));
}
