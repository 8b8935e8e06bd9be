#!/usr/bin/env python3
"""Hostile and mistaken inputs (issue 18), one or more per class of the issue, made here from
scratch (standard library only) in a temporary folder and given to the strata command under a
4 GiB address-space limit (`ulimit -v 4194304`) and a 20 s limit. Prints a table: case, expected
and actual exit status, seconds, whether the message names the file and the field, whether it
says "internal", and the message. Exit status 0 only when every case behaves as expected.

    python3 scripts/hostile-inputs.py [--strata build/strata] [--keep] [CASE...]
"""

import argparse
import json
import os
import resource
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time
import zlib

LIMIT_BYTES = 4194304 * 1024  # ulimit -v 4194304 (KiB)
LIMIT_SECONDS = 20


# --------------------------------------------------------------------------------------------
# file makers


def gzip_bytes(data, trailer=True):
    """A gzip member of `data`; without its CRC32/ISIZE trailer when `trailer` is False."""
    comp = zlib.compressobj(6, zlib.DEFLATED, -15)
    body = comp.compress(data) + comp.flush()
    head = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xff"
    tail = struct.pack("<II", zlib.crc32(data) & 0xFFFFFFFF, len(data) & 0xFFFFFFFF)
    return head + body + (tail if trailer else b"")


def nifti1(dims, datatype=512, bitpix=16, data=b"", pixdim=(1.0, 1.0, 1.0), rank=None):
    """A NIfTI-1 single file: 348-byte header, 4 extension bytes, then `data`."""
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    dim = [rank if rank is not None else len(dims)] + list(dims) + [1] * (7 - len(dims))
    struct.pack_into("<8h", h, 40, *dim)
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, 1.0, *pixdim, 0, 0, 0, 0)
    struct.pack_into("<f", h, 108, 352.0)  # vox_offset
    struct.pack_into("<f", h, 112, 1.0)  # scl_slope
    h[344:348] = b"n+1\x00"
    return bytes(h) + b"\x00" * 4 + data


def nrrd_header(sizes, encoding="raw", extra=""):
    return (
        "NRRD0004\ntype: ushort\ndimension: %d\nsizes: %s\nencoding: %s\nendian: little\n%s"
        % (len(sizes), " ".join(str(s) for s in sizes), encoding, extra)
    ).encode()


def png_chunk(kind, data):
    return (
        struct.pack(">I", len(data))
        + kind
        + data
        + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    )


def png_grey8(width, height, rows):
    """An 8-bit greyscale PNG; `rows` is a list of `height` bytes objects of `width` bytes."""
    raw = b"".join(b"\x00" + r for r in rows)
    return (
        b"\x89PNG\r\n\x1a\n"
        + png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
        + png_chunk(b"IDAT", zlib.compress(raw))
        + png_chunk(b"IEND", b"")
    )


def png_claiming(width, height):
    """A PNG of ~100 bytes whose header claims width x height (8-bit grey)."""
    return (
        b"\x89PNG\r\n\x1a\n"
        + png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
        + png_chunk(b"IDAT", zlib.compress(b"\x00" * 64))
        + png_chunk(b"IEND", b"")
    )


def tiff(pages):
    """A little-endian TIFF; each page (width, height, strip bytes, claimed strip byte count)
    is 8-bit grey, one strip, uncompressed."""
    out = bytearray(b"II*\x00\x00\x00\x00\x00")
    offsets = []
    for width, height, strip, claimed in pages:
        offsets.append((len(out), width, height, claimed))
        out += strip
    ifd_links = []
    first = None
    for strip_at, width, height, claimed in offsets:
        if len(out) % 2:
            out += b"\x00"
        at = len(out)
        if first is None:
            first = at
        else:
            struct.pack_into("<I", out, ifd_links[-1], at)
        entries = [
            (256, 4, 1, width),  # ImageWidth
            (257, 4, 1, height),  # ImageLength
            (258, 3, 1, 8),  # BitsPerSample
            (259, 3, 1, 1),  # Compression: none
            (262, 3, 1, 1),  # Photometric: min-is-black
            (273, 4, 1, strip_at),  # StripOffsets
            (277, 3, 1, 1),  # SamplesPerPixel
            (278, 4, 1, height),  # RowsPerStrip
            (279, 4, 1, claimed),  # StripByteCounts
        ]
        out += struct.pack("<H", len(entries))
        for tag, kind, count, value in entries:
            out += struct.pack("<HHI", tag, kind, count)
            out += struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value)
        ifd_links.append(len(out))
        out += b"\x00\x00\x00\x00"
    struct.pack_into("<I", out, 4, first)
    return bytes(out)


def glb_parts(path):
    data = open(path, "rb").read()
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + n])
    return doc, data[20 + n :]


def glb_write(path, doc, rest):
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I", len(text)) + b"JSON" + text + rest
    open(path, "wb").write(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)


def intensity_stack(folder, width=96, height=96, depth=8, noise=12):
    """A greyscale picture (bright smooth blob plus noise) saved as a PNG stack."""
    os.makedirs(folder)
    state = 18
    for k in range(depth):
        rows = []
        for j in range(height):
            row = bytearray(width)
            for i in range(width):
                dx, dy = i - width / 2, j - height / 2
                r2 = (dx * dx + dy * dy) / (width * width / 16)
                state = (state * 1664525 + 1013904223) & 0xFFFFFFFF
                jitter = (state >> 16) % (2 * noise + 1) - noise
                row[i] = max(1, min(255, int(30 + 200 / (1 + r2)) + jitter))
            rows.append(bytes(row))
        with open(os.path.join(folder, "slice_%04d.png" % k), "wb") as f:
            f.write(png_grey8(width, height, rows))


# --------------------------------------------------------------------------------------------
# the cases


class Case:
    def __init__(self, name, klass, argv, expect=2, names=None, field=None, setup=None, env=None):
        self.name = name
        self.klass = klass
        self.argv = argv  # list; "{strata}" and "{dir}" substituted
        self.expect = expect
        self.names = names  # text the message must contain to name the file (None: not checked)
        self.field = field  # text the message must contain to name the field / what was expected
        self.setup = setup  # callable(dir) run before, may return a cleanup callable
        self.env = env


def cases(strata, node):
    c = []
    S = "{strata}"
    D = "{dir}"
    # --- glTF fields of the wrong type
    for name, pointer, change in [
        ("asset.version", "/asset/version", lambda d: d["asset"].__setitem__("version", 2)),
        ("asset.generator", "/asset/generator", lambda d: d["asset"].__setitem__("generator", 1)),
        ("node name", "/nodes/1/name", lambda d: d["nodes"][1].__setitem__("name", 7)),
        ("material", "/materials/0", lambda d: d["materials"].__setitem__(0, 3)),
        (
            "primitive mode",
            "/meshes/0/primitives/0/mode",
            lambda d: d["meshes"][0]["primitives"][0].__setitem__("mode", "4"),
        ),
        (
            "accessor normalized",
            "/accessors/0/normalized",
            lambda d: d["accessors"][0].__setitem__("normalized", "no"),
        ),
        (
            "pbrMetallicRoughness",
            "/materials/0/pbrMetallicRoughness",
            lambda d: d["materials"][0].__setitem__("pbrMetallicRoughness", 1),
        ),
    ]:
        slug = name.replace(".", "_").replace(" ", "_")

        def make(d, change=change, slug=slug):
            doc, rest = glb_parts(os.path.join(d, "model", "model.glb"))
            change(doc)
            glb_write(os.path.join(d, "wrong_%s.glb" % slug), doc, rest)

        c.append(
            Case("gltf-type-" + slug + "-info", "glTF wrong type", [S, "info", D + "/wrong_%s.glb" % slug],
                 names="wrong_%s.glb" % slug, field=pointer, setup=make)
        )
        c.append(
            Case("gltf-type-" + slug + "-extract", "glTF wrong type",
                 [S, "extract", D + "/wrong_%s.glb" % slug, "-o", D + "/x_%s.ply" % slug],
                 names="wrong_%s.glb" % slug, field=pointer)
        )

    # --- memory bombs
    def shared_chunk(d):
        # every group of the DAG table names the first group's chunk (a small file whose groups
        # would decode one chunk many times: refused by the graph check before any decoding)
        doc, rest = glb_parts(os.path.join(d, "model", "model.glb"))
        ext = doc["nodes"][1]["extensions"]["STRATA_progressive_mesh"]
        view = doc["bufferViews"][ext["dag"]]
        rest = bytearray(rest)
        table = 8 + view.get("byteOffset", 0)  # BIN chunk header, then buffer 0
        groups = struct.unpack_from("<I", rest, table + 8)[0]
        first = struct.unpack_from("<II", rest, table + 16 + 16)
        for g in range(groups):
            struct.pack_into("<II", rest, table + 16 + 32 * g + 16, *first)
        glb_write(os.path.join(d, "shared_chunk.glb"), doc, bytes(rest))

    c.append(Case("glb-groups-share-one-chunk", "memory bomb",
                  [S, "extract", D + "/shared_chunk.glb", "-o", D + "/shared.ply"],
                  names="shared_chunk.glb", field="overlap", setup=shared_chunk))
    def w(path, data):
        def make(d):
            full = os.path.join(d, path)
            os.makedirs(os.path.dirname(full), exist_ok=True)
            with open(full, "wb") as f:
                f.write(data(d) if callable(data) else data)

        return make

    c.append(Case("nifti-8GiB-in-3.8KB", "memory bomb", [S, "info", D + "/bomb.nii"],
                  names="bomb.nii", field="bytes",
                  setup=w("bomb.nii", nifti1((4096, 4096, 255), data=b"\x00" * 3500))))
    c.append(Case("nrrd-8GiB-in-3.8KB", "memory bomb", [S, "info", D + "/bomb.nrrd"],
                  names="bomb.nrrd", field="bytes",
                  setup=w("bomb.nrrd", nrrd_header((4096, 4096, 255)) + b"\n" + b"\x00" * 3500)))
    c.append(Case("nifti-gz-2GB-truncated", "memory bomb", [S, "info", D + "/bomb.nii.gz"],
                  names="bomb.nii.gz", field="truncated",
                  setup=w("bomb.nii.gz", gzip_bytes(nifti1((1024, 1024, 1000), data=b"\x00" * 1000000)))))
    c.append(Case("png-60000^2-in-100B", "memory bomb", [S, "info", D + "/bomb.png"],
                  names="bomb.png", field="60000", setup=w("bomb.png", png_claiming(60000, 60000))))
    c.append(Case("tiff-46000^2", "memory bomb", [S, "info", D + "/bomb.tif"],
                  names="bomb.tif", field="46000",
                  setup=w("bomb.tif", tiff([(46000, 46000, b"\x00" * 64, 46000 * 46000)]))))

    # --- non-regular files
    def fifo_nhdr(d):
        os.mkfifo(os.path.join(d, "data.raw"))
        with open(os.path.join(d, "fifo.nhdr"), "wb") as f:
            f.write(nrrd_header((4, 4, 2), extra="data file: data.raw\n"))

    c.append(Case("nrrd-data-file-fifo", "non-regular file", [S, "info", D + "/fifo.nhdr"],
                  names="data.raw", field="regular file", setup=fifo_nhdr))

    def small_stack(d):
        rows = [bytes([0, 0, 0, 0, 0, 0, 0, 0])] * 2 + [bytes([0, 0, 1, 1, 1, 1, 0, 0])] * 4 + [bytes(8)] * 2
        os.makedirs(os.path.join(d, "stack"), exist_ok=True)
        for k in range(3):
            with open(os.path.join(d, "stack", "slice_%04d.png" % k), "wb") as f:
                f.write(png_grey8(8, 8, rows))

    def fifo_table(d):
        small_stack(d)
        os.mkfifo(os.path.join(d, "table.ctbl"))

    c.append(Case("color-table-fifo", "non-regular file",
                  [S, "build", D + "/stack", "-o", D + "/out_fifo", "--color-table", D + "/table.ctbl"],
                  names="table.ctbl", field="regular file", setup=fifo_table))
    c.append(Case("color-table-dev-zero", "non-regular file",
                  [S, "build", D + "/stack", "-o", D + "/out_zero", "--color-table", "/dev/zero"],
                  names="/dev/zero", field="regular file"))

    def loop(d):
        small_stack(d)
        os.makedirs(os.path.join(d, "loop"))
        shutil.copy(os.path.join(d, "stack", "slice_0000.png"), os.path.join(d, "loop", "a.png"))
        os.symlink("b.png", os.path.join(d, "loop", "c.png"))
        os.symlink("c.png", os.path.join(d, "loop", "b.png"))

    c.append(Case("image-folder-symlink-loop", "non-regular file", [S, "info", D + "/loop"],
                  names="loop", field="symbolic link", setup=loop))

    # --- NRRD detached data outside the header's folder
    for slug, target in [("parent", "../../../etc/passwd"), ("absolute", "/etc/passwd"),
                         ("device", "/dev/urandom")]:
        c.append(Case("nrrd-data-file-" + slug, "data outside folder",
                      [S, "info", D + "/nhdr_%s/escape.nhdr" % slug],
                      names="escape.nhdr",
                      field="not a regular file" if slug == "device" else "outside the folder",
                      setup=w("nhdr_%s/escape.nhdr" % slug,
                              nrrd_header((4, 4, 2), extra="data file: %s\n" % target))))

    # --- truncation
    c.append(Case("nifti-gz-no-trailer", "truncation", [S, "info", D + "/notrailer.nii.gz"],
                  names="notrailer.nii.gz", field="trailer",
                  setup=w("notrailer.nii.gz",
                          gzip_bytes(nifti1((8, 8, 2), data=b"\x01\x00" * 128), trailer=False))))
    c.append(Case("nrrd-gzip-no-trailer", "truncation", [S, "info", D + "/notrailer.nrrd"],
                  names="notrailer.nrrd", field="trailer",
                  setup=w("notrailer.nrrd", nrrd_header((8, 8, 2), encoding="gzip") + b"\n"
                          + gzip_bytes(b"\x01\x00" * 128, trailer=False))))
    c.append(Case("tiff-short-strip", "truncation", [S, "info", D + "/short.tif"],
                  names="short.tif", field="strip",
                  setup=w("short.tif", tiff([(128, 64, b"\x01" * 2000, 2000)]))))

    # --- many-page TIFF: must be read in linear time (exit 0)
    c.append(Case("tiff-20000-pages", "quadratic TIFF", [S, "info", D + "/pages.tif"], expect=0,
                  setup=w("pages.tif", tiff([(4, 4, b"\x00" * 15 + b"\x01", 16)] * 20000))))

    # --- an intensity image taken for a label map
    c.append(Case("greyscale-png-stack", "intensity image",
                  [S, "build", D + "/grey", "-o", D + "/out_grey"],
                  names="grey", field="--force-label-map", setup=lambda d: intensity_stack(os.path.join(d, "grey"))))

    # --- options
    c.append(Case("labels-with-space", "options",
                  [S, "build", D + "/stack", "-o", D + "/out_labels", "-q", "--labels", "1, label 1"],
                  expect=0, setup=small_stack))
    c.append(Case("color-table-missing", "options",
                  [S, "build", D + "/stack", "-o", D + "/out_missing", "--color-table", D + "/absent.ctbl"],
                  names="absent.ctbl", field="no such"))
    c.append(Case("output-is-a-file", "options",
                  [S, "build", D + "/stack", "-o", D + "/afile"], names="afile", field="not a folder",
                  setup=w("afile", b"x")))

    # --- lost or mixed outputs: two objects whose names map to one file name
    def clash(d):
        small = [bytes(8)] * 8
        for k in range(3):
            rows = [bytearray(8) for _ in range(8)]
            for j in range(1, 4):
                for i in range(1, 4):
                    rows[j][i] = 3
                    rows[j + 3][i + 3] = 12
            small = [bytes(r) for r in rows]
            os.makedirs(os.path.join(d, "clash"), exist_ok=True)
            with open(os.path.join(d, "clash", "slice_%04d.png" % k), "wb") as f:
                f.write(png_grey8(8, 8, small))
        with open(os.path.join(d, "clash.json"), "w") as f:
            json.dump({"3": "a_12", "12": "a"}, f)

    c.append(Case("mesh-file-name-clash", "lost outputs",
                  [S, "build", D + "/clash", "-o", D + "/out_clash", "-q", "--color-table", D + "/clash.json"],
                  expect=0, setup=clash))

    # --- an object that cannot be on the progressive model's grid fails the build (exit 1)
    c.append(Case("object-not-on-a-grid", "lost outputs",
                  [S, "build", D + "/sphere", "-o", D + "/model", "-q", "--grid-step", "0.5"],
                  expect=1, names="sphere", field="not on a grid"))

    # --- the web viewer's server
    if node:
        serve = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "web-viewer", "serve.mjs")

        def taken(d):
            s = socket.socket()
            s.bind(("127.0.0.1", 0))
            s.listen(1)
            port = s.getsockname()[1]
            with open(os.path.join(d, "port"), "w") as f:
                f.write(str(port))
            return s.close

        c.append(Case("serve-missing-file", "viewer server", [node, serve, D + "/absent.glb"],
                      names="absent.glb", field="no such file"))
        c.append(Case("serve-port-taken", "viewer server",
                      [node, serve, D + "/model/model.glb", "--port", "{port}"],
                      names="port", field="in use", setup=taken))
    return c


def run(case, strata, d):
    cleanup = case.setup(d) if case.setup else None
    port = open(os.path.join(d, "port")).read() if os.path.exists(os.path.join(d, "port")) else ""
    argv = [a.replace("{strata}", strata).replace("{dir}", d).replace("{port}", port) for a in case.argv]

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (LIMIT_BYTES, LIMIT_BYTES))

    start = time.monotonic()
    try:
        p = subprocess.run(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           preexec_fn=limits, timeout=LIMIT_SECONDS)
        code, err = p.returncode, p.stderr.decode(errors="replace")
    except subprocess.TimeoutExpired as e:
        code, err = "timeout", (e.stderr or b"").decode(errors="replace")
    seconds = time.monotonic() - start
    if cleanup:
        cleanup()
    if os.path.exists(os.path.join(d, "port")):
        os.remove(os.path.join(d, "port"))
    return code, seconds, err.strip()


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("--strata", default=os.path.join(here, "..", "build", "strata"))
    ap.add_argument("--node", default=shutil.which("node"))
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder")
    ap.add_argument("only", nargs="*")
    args = ap.parse_args()
    strata = os.path.abspath(args.strata)
    d = tempfile.mkdtemp(prefix="strata-hostile-")
    # a valid model to break: the built-in sphere phantom
    subprocess.run([strata, "phantom", "t01_sphere", "-o", d + "/sphere", "-q"], check=True)
    subprocess.run([strata, "build", d + "/sphere", "-o", d + "/model", "-q"], check=True)
    rows = []
    failures = 0
    for case in cases(strata, args.node):
        if args.only and not any(o in case.name for o in args.only):
            continue
        code, seconds, err = run(case, strata, d)
        first = err.splitlines()[-1] if err else ""
        ok = code == case.expect and seconds < LIMIT_SECONDS and "internal" not in err
        named = field = "-"
        if case.expect != 0:
            named = "yes" if case.names and case.names in err else "NO"
            field = "yes" if case.field and case.field.lower() in err.lower() else "NO"
            ok = ok and named == "yes" and field == "yes"
        if case.name == "mesh-file-name-clash" and code == 0:
            meshes = sorted(os.listdir(os.path.join(d, "out_clash", "meshes")))
            first = "meshes: " + ", ".join(meshes)
            ok = ok and len(meshes) == 2
        failures += not ok
        rows.append((case.klass, case.name, case.expect, code, seconds, named, field,
                     "internal" in err, "ok" if ok else "FAIL", first))
    print("%-18s %-32s %3s %7s %6s %5s %5s %8s %4s  %s" % (
        "class", "case", "exp", "exit", "s", "file", "field", "internal", "ok", "message (last line)"))
    for r in rows:
        print("%-18s %-32s %3s %7s %6.2f %5s %5s %8s %4s  %s" % (
            r[0], r[1], r[2], r[3], r[4], r[5], r[6], "YES" if r[7] else "no", r[8], r[9][:160]))
    print("%d cases, %d as expected, %d not (limits: ulimit -v %d KiB, %d s)" % (
        len(rows), len(rows) - failures, failures, LIMIT_BYTES // 1024, LIMIT_SECONDS))
    if args.keep:
        print("kept", d)
    else:
        shutil.rmtree(d, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
