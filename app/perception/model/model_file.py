#!/usr/bin/env python3
"""The marking classifier's model files (README.md beside this file).

As a module: the format, read and written (train_cnn.py writes with it).
As a program: the build's generator. It checks a model file (magic, version,
kind, shapes, size, CRC-32 of the payload) and writes the C++ source that
places the payload in the program as it is (the assembler's .incbin: no text
floats for the compiler to parse) and points the classifier at it:

  model_file.py --kind mlp|cnn MODEL.bin OUT.cpp

A file that fails a check fails the build, saying what is wrong.
"""
import argparse
import os
import struct
import sys
import zlib

MAGIC = b"MLWT"
VERSION = 1
KINDS = {"mlp": 1, "cnn": 2}
HEADER = struct.Struct("<4sIII10III")  # magic, version, kind, members, shape[10], elements, crc32
SHAPE_WORDS = 10
# The shape words of each kind, in order (the rest are 0).
SHAPE_NAMES = {
    "mlp": ["inputs", "hidden", "outputs"],
    "cnn": ["input_channels", "patch_rows", "patch_cols", "shape_features", "channels1", "channels2",
            "channels3", "hidden", "outputs"],
}
assert HEADER.size == 64


class ModelFileError(Exception):
    pass


def layout(kind, members, shape):
    """The payload's arrays in order: (member or None, name, element count)."""
    s = dict(zip(SHAPE_NAMES[kind], shape))
    if kind == "mlp":
        inputs, hidden, outputs = s["inputs"], s["hidden"], s["outputs"]
        per_member = [("mean", inputs), ("inv_std", inputs), ("w1", hidden * inputs), ("b1", hidden),
                      ("w2", outputs * hidden), ("b2", outputs)]
        return [(m, name, n) for m in range(members) for name, n in per_member]
    c1, c2, c3, hidden = s["channels1"], s["channels2"], s["channels3"], s["hidden"]
    flat = c3 * (s["patch_rows"] // 4) * (s["patch_cols"] // 4)
    per_member = [("conv1_w", c1 * s["input_channels"] * 9), ("conv1_b", c1), ("conv2_w", c2 * c1 * 9),
                  ("conv2_b", c2), ("conv3_w", c3 * c2 * 9), ("conv3_b", c3),
                  ("fc1_w", hidden * (flat + s["shape_features"])), ("fc1_b", hidden),
                  ("fc2_w", s["outputs"] * hidden), ("fc2_b", s["outputs"])]
    shared = [(None, "shape_mean", s["shape_features"]), (None, "shape_inv_std", s["shape_features"])]
    return shared + [(m, name, n) for m in range(members) for name, n in per_member]


def element_count(kind, members, shape):
    return sum(n for _, _, n in layout(kind, members, shape))


def encode(kind, members, shape, payload):
    """The file's bytes: `payload` is the float32 values' little-endian bytes."""
    shape = list(shape) + [0] * (SHAPE_WORDS - len(shape))
    elements = element_count(kind, members, shape[:len(SHAPE_NAMES[kind])])
    if len(payload) != 4 * elements:
        raise ModelFileError(f"{len(payload)} payload bytes, the shapes need {4 * elements}")
    header = HEADER.pack(MAGIC, VERSION, KINDS[kind], members, *shape, elements, zlib.crc32(payload))
    return header + payload


def write(path, kind, members, shape, payload):
    """Writes the file whole or not at all (a temporary file renamed)."""
    data = encode(kind, members, shape, payload)
    temporary = path + ".part"
    with open(temporary, "wb") as f:
        f.write(data)
    os.replace(temporary, path)


def decode(data, where, kind=None):
    """(kind, members, shape, payload bytes) of a file's bytes, every field
    checked; ModelFileError says what is wrong, `where` first."""
    if len(data) < HEADER.size:
        raise ModelFileError(f"{where}: {len(data)} bytes, shorter than the {HEADER.size}-byte header")
    magic, version, kind_code, members, *rest = HEADER.unpack_from(data)
    shape, elements, crc = rest[:SHAPE_WORDS], rest[SHAPE_WORDS], rest[SHAPE_WORDS + 1]
    if magic != MAGIC:
        raise ModelFileError(f"{where}: not a markloop model file (magic {magic!r}, expected {MAGIC!r})")
    if version != VERSION:
        raise ModelFileError(f"{where}: format version {version}, this build reads version {VERSION}")
    names = {code: name for name, code in KINDS.items()}
    if kind_code not in names:
        raise ModelFileError(f"{where}: unknown model kind {kind_code}")
    if kind is not None and names[kind_code] != kind:
        raise ModelFileError(f"{where}: holds the {names[kind_code]} model, expected the {kind} model")
    kind = names[kind_code]
    used = len(SHAPE_NAMES[kind])
    if members < 1 or any(v < 1 for v in shape[:used]) or any(shape[used:]):
        raise ModelFileError(f"{where}: bad shapes in the header (members {members}, shape {shape})")
    expected = element_count(kind, members, shape[:used])
    if elements != expected:
        raise ModelFileError(f"{where}: header counts {elements} values, its shapes need {expected}")
    if len(data) != HEADER.size + 4 * elements:
        raise ModelFileError(f"{where}: {len(data)} bytes, expected {HEADER.size + 4 * elements} "
                             f"(header and {elements} float32 values)")
    payload = data[HEADER.size:]
    if zlib.crc32(payload) != crc:
        raise ModelFileError(f"{where}: payload CRC-32 0x{zlib.crc32(payload):08x} does not match the "
                             f"header's 0x{crc:08x}: the file is damaged: restore it from git or retrain "
                             "(app/perception/model/README.md)")
    return kind, members, shape[:used], payload


def read(path, kind=None):
    with open(path, "rb") as f:
        return decode(f.read(), path, kind)


def escaped(text):
    """`text` in double quotes, as C++ and the assembler write strings."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def incbin(symbol, path, elements):
    """Top-level assembly placing the payload as a 64-byte aligned,
    read-only array (ELF; x86-64, aarch64 and armhf alike: %-types since
    '@' starts a comment on ARM)."""
    size = 4 * elements
    lines = [".pushsection .rodata." + symbol + ',"a",%progbits', ".balign 64", ".globl " + symbol,
             ".hidden " + symbol, ".type " + symbol + ", %object", symbol + ":",
             ".incbin " + escaped(os.path.abspath(path)) + f", {HEADER.size}, {size}",
             ".size " + symbol + f", {size}", ".popsection"]
    body = "\n".join("    " + escaped(line)[:-1] + '\\n"' for line in lines)
    return (f"__asm__(\n{body});\n\n"
            f'extern "C" __attribute__((visibility("hidden"))) const float {symbol}[{elements}];\n')


def mlp_source(symbol, members, shape):
    inputs, hidden, outputs = shape
    offsets, at = {}, 0
    for m, name, n in layout("mlp", members, shape):
        offsets[(m, name)] = at
        at += n
    fields = ["mean", "inv_std", "w1", "b1", "w2", "b2"]
    nets = ",\n".join("    MlpNet{kFeatureCount, kHidden, kClassifierOutputs, " +
                      ", ".join(f"kWeights + {offsets[(m, f)]}" for f in fields) + "}"
                      for m in range(members))
    return (f"constexpr int kHidden = {hidden};\n"
            f'static_assert(kFeatureCount == {inputs}, "features changed: retrain");\n'
            f'static_assert(kClassifierOutputs == {outputs}, "classes changed: retrain");\n'
            f'static_assert(kHidden <= kMaxHidden && {members} <= kMaxMembers, "model too large");\n\n'
            f"constexpr MlpModel kModel{{{members}, {{{{\n{nets}}}}}}};\n\n"
            "}  // namespace\n\n"
            "const MlpModel& builtin_marking_model() { return kModel; }\n")


def cnn_source(symbol, members, shape):
    s = dict(zip(SHAPE_NAMES["cnn"], shape))
    offsets, at = {}, 0
    for m, name, n in layout("cnn", members, shape):
        offsets[(m, name)] = at
        at += n
    fields = ["conv1_w", "conv1_b", "conv2_w", "conv2_b", "conv3_w", "conv3_b", "shape_mean", "shape_inv_std",
              "fc1_w", "fc1_b", "fc2_w", "fc2_b"]
    shared = ("shape_mean", "shape_inv_std")
    nets = ",\n".join("    CnnNet{" + ", ".join(
        f"kWeights + {offsets[(None if f in shared else m, f)]}" for f in fields) + "}" for m in range(members))
    return (f"static_assert(kCnnInputChannels == {s['input_channels']} && kPatchRows == {s['patch_rows']} &&\n"
            f"              kPatchCols == {s['patch_cols']} && kShapeFeatures == {s['shape_features']},\n"
            '              "patch changed: retrain");\n'
            f"static_assert(kCnnChannels1 == {s['channels1']} && kCnnChannels2 == {s['channels2']} &&\n"
            f"              kCnnChannels3 == {s['channels3']} && kCnnHidden == {s['hidden']} &&\n"
            f"              kClassifierOutputs == {s['outputs']} && kMaxCnnMembers >= {members},\n"
            '              "network changed: retrain");\n\n'
            f"constexpr CnnModel kModel{{{members}, {{\n{nets}}}}};\n\n"
            "}  // namespace\n\n"
            "const CnnModel& builtin_marking_cnn() { return kModel; }\n")


def source(path, shown, kind, members, shape, crc):
    symbol = f"markloop_marking_{kind}_weights"
    elements = element_count(kind, members, shape)
    body = mlp_source(symbol, members, shape) if kind == "mlp" else cnn_source(symbol, members, shape)
    return (f"// GENERATED from {shown} by model_file.py: do not edit.\n"
            f"// {members} networks; {elements} float32 values, CRC-32 0x{crc:08x}.\n"
            "#include <bit>\n\n"
            '#include "app/perception/marking_classifier.hpp"\n\n'
            "static_assert(std::endian::native == std::endian::little,\n"
            '              "the model file holds little-endian floats");\n\n'
            + incbin(symbol, path, elements) +
            "\nnamespace markloop::perception {\nnamespace {\n\n"
            f"constexpr const float* kWeights = {symbol};\n" + body +
            "\n}  // namespace markloop::perception\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kind", choices=sorted(KINDS), required=True, help="the model the file must hold")
    ap.add_argument("model", help="the model file (.bin)")
    ap.add_argument("out", help="the C++ source to write")
    args = ap.parse_args()
    repository = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..")
    shown = os.path.relpath(os.path.abspath(args.model), os.path.abspath(repository))
    try:
        kind, members, shape, payload = read(args.model, args.kind)
    except (ModelFileError, OSError) as e:
        sys.exit(f"model_file.py: {e}")
    text = source(args.model, shown, kind, members, shape, zlib.crc32(payload))
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out + ".part", "w") as f:
        f.write(text)
    os.replace(args.out + ".part", args.out)


if __name__ == "__main__":
    main()
