#!/usr/bin/env python3
"""Cross-checks dbc/markloop.dbc and the generated C++ against canmatrix.

1. Loads the DBC with canmatrix (Debian package python3-canmatrix) strictly:
   any warning or error logged while loading fails the test, and since
   canmatrix itself is lenient, this script adds the checks a strict loader
   (cantools strict mode) makes on canmatrix's model: signals inside the
   frame, no overlaps within a multiplexor page, known nodes and attributes.
2. Checks the message set and E2E/cycle attributes are what the C++ relies on.
3. For every frame the C++ encoder printed (markloop_dbc_vectors):
   - canmatrix decodes the C++ bytes back to the same physical values;
   - canmatrix encodes the same values, this script adds the alive counter and
     its own CRC-8 SAE J1850 (bitwise, independent of the C++ table), and the
     bytes must equal the C++ bytes exactly.
Usage: check_with_canmatrix.py DBC VECTORS_PROGRAM
"""

import decimal
import logging
import subprocess
import sys
import warnings

warnings.simplefilter("ignore", SyntaxWarning)  # canmatrix 0.9.5 source, not our DBC

# canmatrix announces its optional formats (arxml, xls, ...) as warnings on
# import; that is noise, not about our DBC.
_quiet = logging.getLogger("canmatrix")
_quiet.propagate = False
_quiet.addHandler(logging.NullHandler())
try:
    import canmatrix.formats
except ImportError:
    print("FAIL: canmatrix is not installed (apt-get install python3-canmatrix; "
          "bash .ci/setup does it). This check must not be skipped.", file=sys.stderr)
    sys.exit(1)


class Collect(logging.Handler):
    def __init__(self):
        super().__init__(level=logging.WARNING)
        self.records = []

    def emit(self, record):
        self.records.append(record)


def crc8_j1850(data):
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


EXPECTED = {  # id: (name, dlc, cycle ms or None)
    0x120: ("VehicleOdometry", 8, 20),
    0x1A0: ("Command", 4, None),
    0x2A0: ("LoopDetection", 8, None),
    0x2B0: ("Status", 8, 100),
}


def main():
    # The vectors program may come with an emulator in front (cross builds).
    dbc_path, vectors_program = sys.argv[1], sys.argv[2:]
    failures = []

    _quiet.propagate = True
    collect = Collect()
    root = logging.getLogger()
    root.addHandler(collect)
    root.setLevel(logging.WARNING)
    db = canmatrix.formats.loadp_flat(dbc_path)
    root.removeHandler(collect)
    for record in collect.records:
        failures.append(f"canmatrix logged while loading: {record.levelname} {record.getMessage()}")
    if db is None:
        print("FAIL: canmatrix could not load the DBC", file=sys.stderr)
        return 1

    frames = {f.arbitration_id.id: f for f in db.frames}
    failures.extend(strict_checks(db))
    if set(frames) != set(EXPECTED):
        failures.append(f"message ids {sorted(map(hex, frames))} != {sorted(map(hex, EXPECTED))}")
    for frame_id, (name, dlc, cycle) in EXPECTED.items():
        frame = frames.get(frame_id)
        if frame is None:
            continue
        if frame.name != name or frame.size != dlc:
            failures.append(f"{frame_id:#x}: {frame.name}/{frame.size} != {name}/{dlc}")
        if frame.arbitration_id.extended:
            failures.append(f"{name}: must be a standard 11-bit id")
        got_cycle = frame.attributes.get("GenMsgCycleTime")
        if (int(got_cycle) if got_cycle is not None else None) != cycle:
            failures.append(f"{name}: cycle time {got_cycle} != {cycle}")
        if int(frame.attributes.get("E2EDataID", 0)) == 0:
            failures.append(f"{name}: no E2EDataID")
        names = [s.name for s in frame.signals]
        if sum(n.endswith("Crc") for n in names) != 1 or sum(n.endswith("AliveCounter") for n in names) != 1:
            failures.append(f"{name}: needs one *Crc and one *AliveCounter signal")
    loop = frames.get(0x2A0)
    if loop is not None:
        for required in ("QueryFrame", "MatchFrame", "MatchId"):
            if loop.signal_by_name(required) is None:
                failures.append(f"LoopDetection: no signal {required}")
        if not loop.is_multiplexed:
            failures.append("LoopDetection: expected a multiplexed message")

    output = subprocess.run(vectors_program, check=True, capture_output=True, text=True).stdout
    lines = [l for l in output.splitlines() if l.strip()]
    if len(lines) < 10:
        failures.append(f"only {len(lines)} vectors printed")
    for line in lines:
        failures.extend(check_vector(frames, line))

    for f in failures:
        print("FAIL:", f, file=sys.stderr)
    print(f"canmatrix cross-check: {len(lines)} frames compared, {len(failures)} failures")
    return 1 if failures else 0


def occupied(signal):
    """DBC bit numbers (byte * 8 + bit) from canmatrix's internal start bit:
    the LSB for Intel, the MSB in MSB-first linear order for Motorola."""
    if signal.is_little_endian:
        return {signal.start_bit + k for k in range(signal.size)}
    linear = (signal.start_bit + k for k in range(signal.size))
    return {8 * (i // 8) + 7 - i % 8 for i in linear}


def strict_checks(db):
    failures = []
    nodes = {e.name for e in db.ecus}
    for frame in db.frames:
        for name in frame.attributes:
            if name not in db.frame_defines:
                failures.append(f"{frame.name}: attribute {name} has no BA_DEF_")
        for tx in frame.transmitters:
            if tx not in nodes:
                failures.append(f"{frame.name}: unknown sender {tx}")
        pages = {s.mux_val for s in frame.signals if s.mux_val is not None} or {None}
        for page in pages:
            used = {}
            for s in frame.signals:
                if s.mux_val is not None and s.mux_val != page:
                    continue
                bits = occupied(s)
                if min(bits) < 0 or max(bits) >= 8 * frame.size:
                    failures.append(f"{frame.name}.{s.name}: outside the {frame.size}-byte frame")
                for other in sorted({used[b] for b in bits & set(used)}):
                    failures.append(f"{frame.name}.{s.name}: overlaps {other}")
                used.update((b, s.name) for b in bits)
        for s in frame.signals:
            for r in s.receivers:
                if r not in nodes:
                    failures.append(f"{frame.name}.{s.name}: unknown receiver {r}")
            if not s.comment:
                failures.append(f"{frame.name}.{s.name}: no comment")
    return failures


def check_vector(frames, line):
    failures = []
    parts = line.split()
    frame_id, payload = int(parts[0], 16), bytes.fromhex(parts[1])
    fields = {k: decimal.Decimal(v) for k, v in (p.split("=", 1) for p in parts[2:])}
    frame = frames[frame_id]
    where = f"{frame.name} {parts[1]}"

    # canmatrix decodes the C++ bytes.
    decoded = frame.decode(payload)
    crc_name = next(s.name for s in frame.signals if s.name.endswith("Crc"))
    if set(decoded) != set(fields) | {crc_name}:
        failures.append(f"{where}: canmatrix sees signals {sorted(decoded)}, C++ sent {sorted(fields)}")
    for name, value in fields.items():
        if name not in decoded:
            continue
        got = decimal.Decimal(decoded[name].phys_value)
        step = decimal.Decimal(frame.signal_by_name(name).factor)
        if abs(got - value) > step / 2:
            failures.append(f"{where}: {name} decodes to {got} in canmatrix, C++ encoded {value}")

    # canmatrix encodes the same values; we add the CRC.
    raw = {name: frame.signal_by_name(name).phys2raw(value) for name, value in fields.items()}
    raw[crc_name] = 0
    ours = bytearray(frame.encode(raw))
    raw[crc_name] = 0xFF
    crc_byte = next(i for i, (a, b) in enumerate(zip(ours, frame.encode(raw))) if a != b)
    data_id = int(frame.attributes["E2EDataID"])
    ours[crc_byte] = crc8_j1850(bytes([data_id & 0xFF, data_id >> 8]) +
                                bytes(b for i, b in enumerate(ours) if i != crc_byte))
    if bytes(ours) != payload:
        failures.append(f"{where}: canmatrix + independent CRC gives {bytes(ours).hex().upper()}")
    return failures


if __name__ == "__main__":
    sys.exit(main())
