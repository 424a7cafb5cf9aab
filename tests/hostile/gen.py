#!/usr/bin/env python3
"""Hostile-input helpers for tests/hostile/run.sh (standard library only).

  gen.py bitflip SRC DST SEED [NBITS] [FROM] [TO]  flip NBITS random bits in [FROM, TO)
  gen.py nested-yaml DST DEPTH KIND                calibration nested DEPTH levels (seq|map|block)
  gen.py y4m-header SRC DST HEADER [FRAMES]        SRC's frames under another header line
  gen.py y4m-420 SRC DST                           mono YUV4MPEG2 -> C420 (neutral chroma)
  gen.py y4m-frames SRC DST N                      the first N frames of SRC
  gen.py y4m-truncate SRC DST CUT                  SRC less its last CUT bytes
  gen.py y4m-frametag SRC DST K TAG                frame K's FRAME line replaced by TAG
  gen.py can-shift SRC DST SECONDS                 every timestamp + SECONDS
  gen.py can-edit SRC DST LINE TEXT                line LINE (1-based) replaced by TEXT
  gen.py can-stamp SRC DST LINE SECONDS            line LINE's timestamp set to SECONDS
  gen.py can-dlc SRC DST ID BYTES [EVERY]          every EVERY-th frame of ID cut to BYTES bytes
  gen.py route DST KIND N JUMP                     KITTI route of N poses 1 m apart (KIND line|jump|nan|same)
  gen.py png-bomb DST W H                          PNG header claiming WxH grey, tiny IDAT
  gen.py map-info PATH                             "ok LANDMARKS SEQUENCES" | "bad WHY" | "missing"
  gen.py map-edit SRC DST FIELD VALUE              set a header field (landmarks|sequences|k|version), re-CRC
  gen.py map-make DST K N [TEMPLATE]               a sound map of N landmarks, N-K+1 sequences
"""
import os
import struct
import sys
import zlib

# random and re load on first use (start-up time counts: this runs once per case)


def crc32(data):
    return zlib.crc32(data) & 0xFFFFFFFF


def bitflip(src, dst, seed, nbits=1, lo=0, hi=None):
    import random
    data = bytearray(open(src, "rb").read())
    rng = random.Random(int(seed))
    hi = len(data) if hi is None or int(hi) <= 0 or int(hi) > len(data) else int(hi)
    lo = min(int(lo), max(hi - 1, 0))
    for _ in range(int(nbits)):
        if hi <= lo:
            break
        i = rng.randrange(lo, hi)
        data[i] ^= 1 << rng.randrange(8)
    open(dst, "wb").write(data)


def nested_yaml(dst, depth, kind):
    depth = int(depth)
    with open(dst, "w") as f:
        f.write("%YAML:1.0\n---\nimage_width: 1280\nimage_height: 512\n")
        if kind == "seq":
            f.write("deep: " + "[" * depth + "1" + "]" * depth + "\n")
        elif kind == "map":
            f.write("deep: " + "{a: " * depth + "1" + "}" * depth + "\n")
        else:  # block mappings, one level per line (indentation capped to keep the file small)
            f.write("deep:\n")
            for i in range(depth):
                f.write(" " * (1 + i % 200) + "a%d:\n" % i)
            f.write("x: 1\n")


def y4m_split(src):
    """Header line, list of (frame line, payload) for a file whose frames are all alike."""
    import re
    data = open(src, "rb").read()
    nl = data.index(b"\n")
    header = data[:nl].decode()
    w = int(re.search(r" W(\d+)", header).group(1))
    h = int(re.search(r" H(\d+)", header).group(1))
    c = re.search(r" C(\S+)", header)
    chroma = c.group(1) if c else "420jpeg"
    size = w * h
    if chroma.startswith("420"):
        size += 2 * ((w + 1) // 2) * ((h + 1) // 2)
    elif chroma == "422":
        size += 2 * ((w + 1) // 2) * h
    elif chroma == "444":
        size += 2 * w * h
    frames, pos = [], nl + 1
    while pos < len(data):
        e = data.index(b"\n", pos)
        frames.append((data[pos:e + 1], data[e + 1:e + 1 + size]))
        pos = e + 1 + size
    return header, w, h, frames, data


def y4m_header(src, dst, header, nframes=None):
    _, _, _, frames, _ = y4m_split(src)
    if nframes is not None:
        frames = frames[: int(nframes)]
    with open(dst, "wb") as f:
        f.write(header.encode() + b"\n")
        for tag, payload in frames:
            f.write(tag + payload)


def y4m_420(src, dst):
    import re
    header, w, h, frames, _ = y4m_split(src)
    header = re.sub(r" C\S+", "", header) + " C420jpeg"
    chroma = b"\x80" * (2 * ((w + 1) // 2) * ((h + 1) // 2))
    with open(dst, "wb") as f:
        f.write(header.encode() + b"\n")
        for tag, payload in frames:
            f.write(tag + payload + chroma)


def y4m_frames(src, dst, n):
    header, _, _, frames, _ = y4m_split(src)
    y4m_header(src, dst, header, n)


def y4m_truncate(src, dst, cut):
    data = open(src, "rb").read()
    open(dst, "wb").write(data[: max(len(data) - int(cut), 0)])


def y4m_frametag(src, dst, k, tag):
    header, _, _, frames, _ = y4m_split(src)
    k = int(k)
    with open(dst, "wb") as f:
        f.write(header.encode() + b"\n")
        for i, (t, payload) in enumerate(frames):
            f.write((tag.encode() + b"\n") if i == k else t)
            f.write(payload)


def stamp_match(line):
    import re
    return re.match(r"^\((\d+)\.(\d{6})\)", line)


def can_lines(src):
    return open(src).read().splitlines()


def can_write(dst, lines, final_newline=True):
    with open(dst, "w") as f:
        f.write("\n".join(lines) + ("\n" if final_newline else ""))


def can_shift(src, dst, seconds):
    out = []
    for line in can_lines(src):
        m = stamp_match(line)
        if m:
            us = int(m.group(1)) * 1000000 + int(m.group(2)) + int(float(seconds) * 1e6)
            line = "(%010d.%06d)" % (us // 1000000, us % 1000000) + line[m.end():]
        out.append(line)
    can_write(dst, out)


def can_edit(src, dst, line_no, text):
    lines = can_lines(src)
    line_no = int(line_no)
    if line_no == -1:
        line_no = len(lines)
    lines[line_no - 1] = text
    can_write(dst, lines)


def can_stamp(src, dst, line_no, seconds):
    lines = can_lines(src)
    i = int(line_no) - 1
    m = stamp_match(lines[i])
    lines[i] = "(%s.000000)" % seconds + lines[i][m.end():]
    can_write(dst, lines)


def can_dlc(src, dst, can_id, nbytes, every=1):
    out, n = [], 0
    for line in can_lines(src):
        parts = line.split(" ")
        if len(parts) >= 3 and parts[2].upper().startswith(can_id.upper() + "#"):
            if n % int(every) == 0:
                ident, data = parts[2].split("#", 1)
                parts[2] = ident + "#" + data[: 2 * int(nbytes)]
                line = " ".join(parts)
            n += 1
        out.append(line)
    can_write(dst, out)


def route(dst, kind, n, jump):
    n, jump = int(n), float(jump)
    with open(dst, "w") as f:
        x = 0.0
        for i in range(n):
            if kind == "jump" and i == n // 2:
                x += jump
            elif kind != "same":
                x += 1.0
            tx = "nan" if (kind == "nan" and i == n // 2) else repr(x)
            f.write("1 0 0 %s 0 1 0 0 0 0 1 0\n" % tx)


def png_bomb(dst, w, h):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", int(w), int(h), 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\x00" * 4096)
    with open(dst, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


def map_info(path):
    if not os.path.lexists(path):
        return "missing"
    if not os.path.isfile(path):
        return "bad not a regular file"
    data = open(path, "rb").read()
    if len(data) < 64 or data[:8] != b"MLOOPMAP":
        return "bad header (%d bytes)" % len(data)
    if struct.unpack_from("<I", data, 60)[0] != crc32(data[:60]):
        return "bad header checksum"
    landmarks, sequences, payload = struct.unpack_from("<QQQ", data, 24)
    if len(data) != 64 + payload:
        return "bad size %d, header says %d" % (len(data), 64 + payload)
    if struct.unpack_from("<I", data, 48)[0] != crc32(data[64:]):
        return "bad payload checksum"
    return "ok %d %d" % (landmarks, sequences)


def map_edit(src, dst, field, value):
    data = bytearray(open(src, "rb").read())
    offsets = {"version": (8, "<I"), "k": (16, "<I"), "landmarks": (24, "<Q"), "sequences": (32, "<Q"),
               "payload": (40, "<Q")}
    off, fmt = offsets[field]
    struct.pack_into(fmt, data, off, int(value))
    struct.pack_into("<I", data, 60, crc32(bytes(data[:60])))
    open(dst, "wb").write(data)


def map_make(dst, k, nlandmarks, template=None):
    """A sound map of NLANDMARKS landmarks in a row and every k consecutive ones as a sequence
    (version and record sizes from TEMPLATE, a map markloop wrote, when given)."""
    k, n = int(k), int(nlandmarks)
    body = bytearray()
    for i in range(n):
        x, y = 10.0 + 3.0 * i, (-1.5 if i % 2 else 1.5)
        body += struct.pack("<HHII", 1 + i % 5, 3, 10 * i, 10 * i + 5)
        body += struct.pack("<fffff", x, y, x - 8.0, 0.0, 0.0)
        body += bytes([1, 0, 0, 0]) + struct.pack("<dd", 0.3 * i, 3.0 * i)
    nseq = max(n - k + 1, 0)
    for s in range(nseq):
        body += struct.pack("<" + "I" * k, *range(s, s + k))
    header = bytearray(64)
    header[:8] = b"MLOOPMAP"
    struct.pack_into("<IIII", header, 8, 1, 64, k, 52)
    if template:
        header[8:16] = open(template, "rb").read()[8:16]
    struct.pack_into("<QQQ", header, 24, n, nseq, len(body))
    struct.pack_into("<I", header, 48, crc32(bytes(body)))
    struct.pack_into("<I", header, 60, crc32(bytes(header[:60])))
    open(dst, "wb").write(bytes(header) + bytes(body))


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    cmd, args = argv[1], argv[2:]
    table = {
        "bitflip": bitflip, "nested-yaml": nested_yaml, "y4m-header": y4m_header, "y4m-420": y4m_420,
        "y4m-frames": y4m_frames, "y4m-truncate": y4m_truncate, "y4m-frametag": y4m_frametag,
        "can-shift": can_shift, "can-edit": can_edit, "can-stamp": can_stamp, "can-dlc": can_dlc,
        "route": route, "png-bomb": png_bomb, "map-edit": map_edit, "map-make": map_make,
    }
    if cmd == "map-info":
        print(map_info(args[0]))
        return 0
    if cmd not in table:
        print("gen.py: unknown command " + cmd, file=sys.stderr)
        return 2
    table[cmd](*args)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
