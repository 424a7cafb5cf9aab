#!/usr/bin/env python3
"""Generates markloop's C++ CAN encoders/decoders and docs from a DBC file.

Python 3 standard library only. Parses the DBC subset markloop uses (VERSION,
NS_, BS_, BU_, BO_, SG_ incl. multiplexor M / mN, CM_, BA_DEF_, BA_DEF_DEF_,
BA_, VAL_) with a real tokenizer, validates the wire layout and the E2E
conventions, and fails loudly on anything it does not understand.

Conventions the DBC must follow (checked here):
  - every message has exactly one E2E CRC signal (name ends in "Crc", 8 bits,
    one whole byte, unsigned) and one alive counter (name ends in
    "AliveCounter", 4 bits, unsigned), and a non-zero, unique "E2EDataID"
    attribute. CRC-8 SAE J1850 (poly 0x1D, init 0xFF, xor-out 0xFF) runs over
    data id low byte, data id high byte, then the payload bytes in increasing
    index except the CRC byte.
  - "GenMsgSendType" Cyclic messages have "GenMsgCycleTime" > 0; their
    receive timeout is TIMEOUT_CYCLES cycle times.
  - min/max lie on the raw grid and inside the raw bit range; signals do not
    overlap (per multiplexor page) and fit the DLC.

Usage:
  generate.py DBC --header OUT.hpp [--markdown OUT.md] [--node MARKLOOP]
  generate.py DBC --markdown -                 # table to stdout
  generate.py DBC --update-readme README.md    # rewrite the generated section
  generate.py DBC --check-readme README.md     # exit 1 if it is stale
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

TIMEOUT_CYCLES = 3
README_BEGIN = "<!-- BEGIN GENERATED: dbc/generate.py --update-readme; do not edit by hand -->"
README_END = "<!-- END GENERATED -->"


class DbcError(Exception):
    pass


# --------------------------------------------------------------------------
# Tokenizer

@dataclass
class Token:
    kind: str  # "ident", "number", "string", "punct"
    text: str
    line: int


_TOKEN_RE = re.compile(
    r"""
    (?P<ws>[ \t\r]+)
  | (?P<newline>\n)
  | (?P<comment>//[^\n]*)
  | (?P<string>"(?:[^"\\]|\\.)*")
  | (?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![A-Za-z_]))
  | (?P<ident>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<punct>[:;|@()\[\],+-])
    """,
    re.VERBOSE,
)


def tokenize(text: str) -> list[Token]:
    tokens: list[Token] = []
    pos, line = 0, 1
    while pos < len(text):
        m = _TOKEN_RE.match(text, pos)
        if not m:
            raise DbcError(f"line {line}: unexpected character {text[pos]!r}")
        kind = m.lastgroup
        value = m.group()
        if kind == "string":
            tokens.append(Token("string", value[1:-1].replace('\\"', '"').replace("\\\\", "\\"), line))
        elif kind in ("number", "ident", "punct"):
            tokens.append(Token(kind, value, line))
        line += value.count("\n")
        pos = m.end()
    return tokens


# --------------------------------------------------------------------------
# Model

@dataclass
class Signal:
    name: str
    start_bit: int
    length: int
    intel: bool
    signed: bool
    factor: float
    offset: float
    minimum: float
    maximum: float
    unit: str
    receivers: list[str]
    is_multiplexor: bool = False
    mux_value: int | None = None
    comment: str = ""
    values: list[tuple[int, str]] = field(default_factory=list)
    # derived
    raw_min: int = 0
    raw_max: int = 0


@dataclass
class Message:
    frame_id: int
    name: str
    length: int
    sender: str
    signals: list[Signal] = field(default_factory=list)
    comment: str = ""
    attributes: dict[str, object] = field(default_factory=dict)
    # derived
    crc: Signal | None = None
    counter: Signal | None = None
    multiplexor: Signal | None = None
    cycle_ms: int = 0
    data_id: int = 0

    def signal(self, name: str) -> Signal:
        for s in self.signals:
            if s.name == name:
                return s
        raise DbcError(f"message {self.name}: no signal {name}")

    @property
    def payload_signals(self) -> list[Signal]:
        return [s for s in self.signals if s not in (self.crc, self.counter)]


@dataclass
class AttributeDef:
    object_type: str  # "", "BU_", "BO_", "SG_", "EV_"
    name: str
    value_type: str
    enum_values: list[str]
    default: object = None


@dataclass
class Database:
    version: str = ""
    nodes: list[str] = field(default_factory=list)
    messages: list[Message] = field(default_factory=list)
    comment: str = ""
    node_comments: dict[str, str] = field(default_factory=dict)
    attribute_defs: dict[str, AttributeDef] = field(default_factory=dict)
    attributes: dict[str, object] = field(default_factory=dict)

    def message(self, frame_id: int) -> Message:
        for m in self.messages:
            if m.frame_id == frame_id:
                return m
        raise DbcError(f"no message with id {frame_id}")


# --------------------------------------------------------------------------
# Parser

class Parser:
    SECTION_KEYWORDS = {"VERSION", "NS_", "BS_", "BU_", "BO_", "SG_", "CM_", "BA_DEF_",
                        "BA_DEF_DEF_", "BA_", "VAL_"}

    def __init__(self, tokens: list[Token]):
        self.tokens = tokens
        self.pos = 0
        self.db = Database()
        self.current: Message | None = None

    # token helpers
    def peek(self, offset: int = 0) -> Token | None:
        i = self.pos + offset
        return self.tokens[i] if i < len(self.tokens) else None

    def next(self) -> Token:
        tok = self.peek()
        if tok is None:
            raise DbcError("unexpected end of file")
        self.pos += 1
        return tok

    def expect(self, kind: str, text: str | None = None) -> Token:
        tok = self.next()
        if tok.kind != kind or (text is not None and tok.text != text):
            want = text if text is not None else kind
            raise DbcError(f"line {tok.line}: expected {want}, found {tok.text!r}")
        return tok

    def number(self) -> float:
        tok = self.expect("number")
        return float(tok.text)

    def integer(self) -> int:
        tok = self.expect("number")
        if not re.fullmatch(r"[-+]?\d+", tok.text):
            raise DbcError(f"line {tok.line}: expected an integer, found {tok.text}")
        return int(tok.text)

    def at(self, kind: str, text: str | None = None) -> bool:
        tok = self.peek()
        return tok is not None and tok.kind == kind and (text is None or tok.text == text)

    # grammar
    def parse(self) -> Database:
        while self.peek() is not None:
            tok = self.next()
            if tok.kind != "ident":
                raise DbcError(f"line {tok.line}: expected a keyword, found {tok.text!r}")
            handler = {
                "VERSION": self.parse_version, "NS_": self.parse_ns, "BS_": self.parse_bs,
                "BU_": self.parse_bu, "BO_": self.parse_bo, "SG_": self.parse_sg,
                "CM_": self.parse_cm, "BA_DEF_": self.parse_ba_def,
                "BA_DEF_DEF_": self.parse_ba_def_def, "BA_": self.parse_ba, "VAL_": self.parse_val,
            }.get(tok.text)
            if handler is None:
                raise DbcError(f"line {tok.line}: unsupported DBC keyword {tok.text}")
            handler(tok)
        return self.db

    def parse_version(self, tok: Token) -> None:
        self.db.version = self.expect("string").text

    def parse_ns(self, tok: Token) -> None:
        self.expect("punct", ":")
        # The new-symbols list names keywords; it ends where BS_ begins.
        while not self.at("ident", "BS_"):
            self.expect("ident")

    def parse_bs(self, tok: Token) -> None:
        self.expect("punct", ":")
        nxt = self.peek()
        if nxt is not None and nxt.line == tok.line:
            raise DbcError(f"line {tok.line}: bit timing (BS_) must be empty")

    def parse_bu(self, tok: Token) -> None:
        self.expect("punct", ":")
        while self.peek() is not None and self.peek().line == tok.line:
            self.db.nodes.append(self.expect("ident").text)

    def parse_bo(self, tok: Token) -> None:
        frame_id = self.integer()
        name = self.expect("ident").text
        self.expect("punct", ":")
        length = self.integer()
        sender = self.expect("ident").text
        message = Message(frame_id, name, length, sender)
        self.db.messages.append(message)
        self.current = message

    def parse_sg(self, tok: Token) -> None:
        if self.current is None:
            raise DbcError(f"line {tok.line}: SG_ outside a BO_")
        name = self.expect("ident").text
        is_multiplexor, mux_value = False, None
        if self.at("ident"):
            mux = self.next()
            if mux.text == "M":
                is_multiplexor = True
            elif re.fullmatch(r"m\d+", mux.text):
                mux_value = int(mux.text[1:])
            else:
                raise DbcError(f"line {mux.line}: unsupported multiplex indicator {mux.text}")
        self.expect("punct", ":")
        start_bit = self.integer()
        self.expect("punct", "|")
        length = self.integer()
        self.expect("punct", "@")
        order = self.integer()
        if order not in (0, 1):
            raise DbcError(f"line {tok.line}: byte order must be @0 or @1")
        sign = self.expect("punct").text
        if sign not in "+-":
            raise DbcError(f"line {tok.line}: signedness must be + or -")
        self.expect("punct", "(")
        factor = self.number()
        self.expect("punct", ",")
        offset = self.number()
        self.expect("punct", ")")
        self.expect("punct", "[")
        minimum = self.number()
        self.expect("punct", "|")
        maximum = self.number()
        self.expect("punct", "]")
        unit = self.expect("string").text
        receivers = [self.expect("ident").text]
        while self.at("punct", ","):
            self.next()
            receivers.append(self.expect("ident").text)
        nxt = self.peek()
        if nxt is not None and nxt.line == tok.line:
            raise DbcError(f"line {tok.line}: unexpected {nxt.text!r} after signal {name}")
        self.current.signals.append(Signal(
            name, start_bit, length, order == 1, sign == "-", factor, offset, minimum, maximum,
            unit, receivers, is_multiplexor, mux_value))

    def parse_cm(self, tok: Token) -> None:
        if self.at("string"):
            self.db.comment = self.next().text
        else:
            kind = self.expect("ident").text
            # (Python evaluates an assignment's right side first: read in order.)
            if kind == "BU_":
                node = self.expect("ident").text
                if node not in self.db.nodes:
                    raise DbcError(f"line {tok.line}: comment for unknown node {node}")
                self.db.node_comments[node] = self.expect("string").text
            elif kind == "BO_":
                message = self.db.message(self.integer())
                message.comment = self.expect("string").text
            elif kind == "SG_":
                message = self.db.message(self.integer())
                signal = message.signal(self.expect("ident").text)
                signal.comment = self.expect("string").text
            else:
                raise DbcError(f"line {tok.line}: unsupported comment target {kind}")
        self.expect("punct", ";")

    def parse_ba_def(self, tok: Token) -> None:
        object_type = ""
        if self.at("ident"):
            object_type = self.next().text
            if object_type not in ("BU_", "BO_", "SG_", "EV_"):
                raise DbcError(f"line {tok.line}: unsupported attribute object {object_type}")
        name = self.expect("string").text
        value_type = self.expect("ident").text
        enum_values: list[str] = []
        if value_type in ("INT", "HEX", "FLOAT"):
            self.number()
            self.number()
        elif value_type == "ENUM":
            enum_values.append(self.expect("string").text)
            while self.at("punct", ","):
                self.next()
                enum_values.append(self.expect("string").text)
        elif value_type != "STRING":
            raise DbcError(f"line {tok.line}: unsupported attribute type {value_type}")
        self.expect("punct", ";")
        self.db.attribute_defs[name] = AttributeDef(object_type, name, value_type, enum_values)

    def attribute_value(self, definition: AttributeDef, line: int) -> object:
        tok = self.next()
        if definition.value_type == "STRING":
            if tok.kind != "string":
                raise DbcError(f"line {line}: attribute {definition.name} needs a string")
            return tok.text
        if definition.value_type == "ENUM":
            if tok.kind == "string":
                if tok.text not in definition.enum_values:
                    raise DbcError(f"line {line}: {tok.text!r} is not a value of {definition.name}")
                return tok.text
            index = int(tok.text)
            if not 0 <= index < len(definition.enum_values):
                raise DbcError(f"line {line}: enum index {index} out of range for {definition.name}")
            return definition.enum_values[index]
        if tok.kind != "number":
            raise DbcError(f"line {line}: attribute {definition.name} needs a number")
        return float(tok.text) if definition.value_type == "FLOAT" else int(tok.text)

    def definition(self, name: str, line: int) -> AttributeDef:
        if name not in self.db.attribute_defs:
            raise DbcError(f"line {line}: attribute {name} used before its BA_DEF_")
        return self.db.attribute_defs[name]

    def parse_ba_def_def(self, tok: Token) -> None:
        definition = self.definition(self.expect("string").text, tok.line)
        definition.default = self.attribute_value(definition, tok.line)
        self.expect("punct", ";")

    def parse_ba(self, tok: Token) -> None:
        definition = self.definition(self.expect("string").text, tok.line)
        if self.at("ident"):
            kind = self.next().text
            if kind != definition.object_type:
                raise DbcError(f"line {tok.line}: attribute {definition.name} is not for {kind}")
            if kind == "BO_":
                target = self.db.message(self.integer()).attributes
            else:
                raise DbcError(f"line {tok.line}: unsupported attribute target {kind}")
        else:
            if definition.object_type != "":
                raise DbcError(f"line {tok.line}: attribute {definition.name} needs a target")
            target = self.db.attributes
        target[definition.name] = self.attribute_value(definition, tok.line)
        self.expect("punct", ";")

    def parse_val(self, tok: Token) -> None:
        message = self.db.message(self.integer())
        signal = message.signal(self.expect("ident").text)
        while not self.at("punct", ";"):
            value = self.integer()
            signal.values.append((value, self.expect("string").text))
        self.next()
        signal.values.sort()


def parse_dbc(text: str) -> Database:
    db = Parser(tokenize(text)).parse()
    validate(db)
    return db


# --------------------------------------------------------------------------
# Validation

def attribute(db: Database, message: Message, name: str) -> object:
    if name in message.attributes:
        return message.attributes[name]
    if name not in db.attribute_defs:
        raise DbcError(f"attribute {name} is not defined (BA_DEF_)")
    default = db.attribute_defs[name].default
    if default is None:
        raise DbcError(f"attribute {name} has no default (BA_DEF_DEF_)")
    return default


def on_grid(value: float, signal: Signal, what: str, where: str) -> int:
    q = (value - signal.offset) / signal.factor
    r = round(q)
    if abs(q - r) > 1e-6 * max(1.0, abs(q)):
        raise DbcError(f"{where}: {what} {value} is not a multiple of the factor {signal.factor}")
    return int(r)


def occupied_bits(signal: Signal) -> set[int]:
    """DBC bit numbers the signal covers."""
    bits = set()
    position = signal.start_bit
    for _ in range(signal.length):
        bits.add(position)
        if signal.intel:
            position += 1
        elif position % 8 == 0:
            position += 15  # Motorola: from bit 0 of a byte to bit 7 of the next
        else:
            position -= 1
    return bits


def validate(db: Database) -> None:
    if not db.nodes:
        raise DbcError("no nodes (BU_)")
    ids, names, data_ids = set(), set(), set()
    for m in db.messages:
        where = f"message {m.name}"
        if m.frame_id >= 0x800:
            raise DbcError(f"{where}: id {m.frame_id:#x} is not an 11-bit standard id")
        if m.frame_id in ids or m.name in names:
            raise DbcError(f"{where}: duplicate id or name")
        ids.add(m.frame_id)
        names.add(m.name)
        if not 1 <= m.length <= 8:
            raise DbcError(f"{where}: DLC {m.length} is not 1..8")
        if m.sender not in db.nodes:
            raise DbcError(f"{where}: unknown sender {m.sender}")
        if not m.comment:
            raise DbcError(f"{where}: no comment (CM_ BO_)")

        send_type = attribute(db, m, "GenMsgSendType")
        m.cycle_ms = int(attribute(db, m, "GenMsgCycleTime"))
        if send_type == "Cyclic" and m.cycle_ms <= 0:
            raise DbcError(f"{where}: cyclic but GenMsgCycleTime is {m.cycle_ms}")
        if send_type != "Cyclic" and m.cycle_ms != 0:
            raise DbcError(f"{where}: has a cycle time but is not Cyclic")
        m.data_id = int(attribute(db, m, "E2EDataID"))
        if not 0 < m.data_id <= 0xFFFF or m.data_id in data_ids:
            raise DbcError(f"{where}: E2EDataID must be unique and in 1..65535")
        data_ids.add(m.data_id)

        crcs = [s for s in m.signals if s.name.endswith("Crc")]
        counters = [s for s in m.signals if s.name.endswith("AliveCounter")]
        muxes = [s for s in m.signals if s.is_multiplexor]
        if len(crcs) != 1 or len(counters) != 1:
            raise DbcError(f"{where}: needs exactly one *Crc and one *AliveCounter signal")
        m.crc, m.counter = crcs[0], counters[0]
        crc_aligned = m.crc.start_bit % 8 == (0 if m.crc.intel else 7)
        if m.crc.length != 8 or m.crc.signed or not crc_aligned or m.crc.mux_value is not None:
            raise DbcError(f"{where}: the CRC must be one whole unsigned byte in every page")
        if m.counter.length != 4 or m.counter.signed or m.counter.mux_value is not None:
            raise DbcError(f"{where}: the alive counter must be 4 unsigned bits in every page")
        if len(muxes) > 1:
            raise DbcError(f"{where}: only one multiplexor is supported")
        m.multiplexor = muxes[0] if muxes else None
        if m.multiplexor is None and any(s.mux_value is not None for s in m.signals):
            raise DbcError(f"{where}: multiplexed signals without a multiplexor")

        for s in m.signals:
            sw = f"{where} signal {s.name}"
            if not s.comment:
                raise DbcError(f"{sw}: no comment (CM_ SG_)")
            if not 1 <= s.length <= 32:
                raise DbcError(f"{sw}: length must be 1..32 bits")
            if s.factor <= 0:
                raise DbcError(f"{sw}: factor must be positive")
            if s.minimum > s.maximum:
                raise DbcError(f"{sw}: min > max")
            for r in s.receivers:
                if r not in db.nodes:
                    raise DbcError(f"{sw}: unknown receiver {r}")
            if s.is_multiplexor and (s.signed or s.factor != 1 or s.offset != 0):
                raise DbcError(f"{sw}: a multiplexor must be unsigned and unscaled")
            s.raw_min = on_grid(s.minimum, s, "min", sw)
            s.raw_max = on_grid(s.maximum, s, "max", sw)
            lo, hi = ((-(1 << (s.length - 1)), (1 << (s.length - 1)) - 1) if s.signed
                      else (0, (1 << s.length) - 1))
            if s.raw_min < lo or s.raw_max > hi:
                raise DbcError(f"{sw}: [min|max] needs raw [{s.raw_min}, {s.raw_max}], "
                               f"the bits hold [{lo}, {hi}]")
            for value, text in s.values:
                if not s.raw_min <= value <= s.raw_max:
                    raise DbcError(f"{sw}: value {value} ({text}) outside [min|max]")
            if len({identifier(t) for _, t in s.values}) != len(s.values):
                raise DbcError(f"{sw}: value descriptions do not give unique names")
            bits = occupied_bits(s)
            if max(bits) >= 8 * m.length or min(bits) < 0:
                raise DbcError(f"{sw}: does not fit the DLC {m.length}")

        mux_values = sorted({s.mux_value for s in m.signals if s.mux_value is not None})
        if m.multiplexor is not None:
            mux = m.multiplexor
            for v in mux_values:
                if not mux.raw_min <= v <= mux.raw_max:
                    raise DbcError(f"{where}: page m{v} outside the multiplexor's [min|max]")
            if mux.values and [v for v, _ in mux.values] != mux_values:
                raise DbcError(f"{where}: the multiplexor's value table must list exactly the pages")
        for page in (mux_values or [None]):
            used: dict[int, str] = {}
            for s in m.signals:
                if s.mux_value is not None and s.mux_value != page:
                    continue
                for b in occupied_bits(s):
                    if b in used:
                        raise DbcError(f"{where}: {s.name} overlaps {used[b]} at bit {b}")
                    used[b] = s.name


# --------------------------------------------------------------------------
# Naming and C++ types

def identifier(text: str) -> str:
    """'Initialising' -> Initialising, 'save map' -> SaveMap."""
    words = re.findall(r"[A-Za-z0-9]+", text)
    name = "".join(w[0].upper() + w[1:] for w in words)
    if not name or name[0].isdigit():
        name = "V" + name
    return name


def snake(name: str) -> str:
    s = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", name)
    s = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", s)
    return s.lower()


UNIT_SUFFIX = {"m": "m", "s": "s", "ms": "ms", "deg": "deg", "deg/s": "deg_per_s",
               "m/s": "m_per_s", "km/h": "km_per_h", "%": "percent", "rad": "rad",
               "rad/s": "rad_per_s", "m/s2": "m_per_s2", "": ""}


def member_name(signal: Signal) -> str:
    if signal.unit not in UNIT_SUFFIX:
        raise DbcError(f"signal {signal.name}: add unit {signal.unit!r} to UNIT_SUFFIX")
    suffix = UNIT_SUFFIX[signal.unit]
    return snake(signal.name) + ("_" + suffix if suffix else "")


def kind_of(signal: Signal) -> str:
    if signal.values:
        return "enum"
    unscaled = signal.factor == 1 and signal.offset == 0
    if unscaled and not signal.signed and signal.length == 1 and (signal.raw_min, signal.raw_max) == (0, 1):
        return "bool"
    if unscaled:
        return "integer"
    return "double"


def integer_type(lo: int, hi: int) -> str:
    for bits in (8, 16, 32, 64):
        if lo >= 0 and hi < (1 << bits):
            return f"std::uint{bits}_t"
        if lo < 0 and -(1 << (bits - 1)) <= lo and hi < (1 << (bits - 1)):
            return f"std::int{bits}_t"
    raise DbcError(f"range [{lo}, {hi}] needs more than 64 bits")


def cpp_type(signal: Signal) -> str:
    kind = kind_of(signal)
    if kind == "enum":
        return signal.name
    if kind == "bool":
        return "bool"
    if kind == "integer":
        return integer_type(signal.raw_min, signal.raw_max)
    return "double"


def cpp_double(value: float) -> str:
    text = repr(float(value))
    return text if ("." in text or "e" in text) else text + ".0"


def cpp_int(value: int) -> str:
    # INT64_MIN-safe literals are not needed: raw ranges are at most 32 bits.
    return f"std::int64_t{{{value}}}"


def default_value(signal: Signal) -> str:
    kind = kind_of(signal)
    raw = 0 if signal.raw_min <= 0 <= signal.raw_max else signal.raw_min
    if kind == "enum":
        raw = raw if raw in dict(signal.values) else signal.values[0][0]
        return f"{signal.name}::{identifier(dict(signal.values)[raw])}"
    if kind == "bool":
        return "false"
    if kind == "integer":
        return str(raw)
    return cpp_double(raw * signal.factor + signal.offset)


def layout_name(signal: Signal) -> str:
    return "k" + signal.name


def cpp_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def wrap_comment(text: str, indent: str, width: int = 96) -> list[str]:
    lines, line = [], ""
    for word in text.split():
        if line and len(indent) + 3 + len(line) + 1 + len(word) > width:
            lines.append(f"{indent}// {line}")
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        lines.append(f"{indent}// {line}")
    return lines


def range_text(signal: Signal) -> str:
    unit = f" {signal.unit}" if signal.unit else ""
    return f"[{fmt(signal.minimum)}, {fmt(signal.maximum)}]{unit}, raw {fmt(signal.factor)} per bit"


def fmt(value: float) -> str:
    return f"{value:.10g}"


# --------------------------------------------------------------------------
# C++ emission

def emit_header(db: Database, dbc_name: str, node: str) -> str:
    if node not in db.nodes:
        raise DbcError(f"node {node} is not in BU_")
    out: list[str] = []
    w = out.append
    w(f"// Generated by dbc/generate.py from {dbc_name}. Do not edit: change the DBC.")
    w("//")
    w("// Per message: a struct of physical values with its wire constants, encode()")
    w("// (rounds, saturates to [min|max], fills alive counter and CRC), and decode()")
    w("// (checks length, CRC, alive counter, ranges; writes `out` only on success).")
    w("// No heap, no exceptions. E2E details: dbc/e2e.hpp.")
    w("#pragma once")
    w("")
    for inc in ("array", "chrono", "cstddef", "cstdint", "span", "string_view"):
        w(f"#include <{inc}>")
    w("")
    for inc in ("bits.hpp", "codec.hpp", "e2e.hpp", "receive.hpp"):
        w(f'#include "dbc/{inc}"')
    w("")
    w("namespace markloop::dbc {")
    w("")
    w(f"inline constexpr std::string_view kDbcVersion = {cpp_string(db.version)};")
    w(f"inline constexpr int kTimeoutCycles = {TIMEOUT_CYCLES};  // receive timeout, in cycle times")
    w("")

    # Value tables.
    for m in db.messages:
        for s in m.signals:
            if not s.values:
                continue
            underlying = integer_type(min(v for v, _ in s.values), max(v for v, _ in s.values))
            out.extend(wrap_comment(f"{m.name}.{s.name}: {s.comment}", ""))
            w(f"enum class {s.name} : {underlying} {{")
            for value, text in s.values:
                w(f"  {identifier(text)} = {value},")
            w("};")
            w("")
            w(f"constexpr std::string_view to_string({s.name} value) noexcept {{")
            w("  switch (value) {")
            for value, text in s.values:
                w(f"    case {s.name}::{identifier(text)}: return {cpp_string(identifier(text))};")
            w("  }")
            w('  return "?";')
            w("}")
            w("")

    for m in db.messages:
        emit_message(out, db, m)

    received = [m for m in db.messages if m.sender != node and any(node in s.receivers for s in m.signals)]
    sent = [m for m in db.messages if m.sender == node]
    w(f"// CAN ids the node {node} receives (for SocketCAN filters) and sends.")
    w(f"inline constexpr std::array<std::uint32_t, {len(received)}> kReceivedIds{{"
      + ", ".join(f"{m.name}::kId" for m in received) + "};")
    w(f"inline constexpr std::array<std::uint32_t, {len(sent)}> kSentIds{{"
      + ", ".join(f"{m.name}::kId" for m in sent) + "};")
    w("")
    w("// Name of the message with this CAN id, or an empty view.")
    w("constexpr std::string_view message_name(std::uint32_t id) noexcept {")
    w("  switch (id) {")
    for m in db.messages:
        w(f"    case {m.name}::kId: return {m.name}::kName;")
    w("    default: return {};")
    w("  }")
    w("}")
    w("")
    w("}  // namespace markloop::dbc")
    return "\n".join(out) + "\n"


def emit_message(out: list[str], db: Database, m: Message) -> None:
    w = out.append
    ns = snake(m.name)
    mux = m.multiplexor
    pages = sorted({s.mux_value for s in m.signals if s.mux_value is not None})

    # Layouts.
    w(f"namespace layout::{ns} {{")
    for s in m.signals:
        order = "ByteOrder::Intel" if s.intel else "ByteOrder::Motorola"
        signed = "true" if s.signed else "false"
        where = "" if s.mux_value is None else f"  // page {s.mux_value}"
        w(f"inline constexpr SignalLayout {layout_name(s)}{{{s.start_bit}, {s.length}, {order}, {signed}}};{where}")
    w(f"}}  // namespace layout::{ns}")
    w("")

    # Struct.
    out.extend(wrap_comment(m.comment, ""))
    w(f"struct {m.name} {{")
    w(f"  static constexpr std::uint32_t kId = 0x{m.frame_id:03X};")
    w(f"  static constexpr std::string_view kName = {cpp_string(m.name)};")
    w(f"  static constexpr std::uint8_t kLength = {m.length};  // DLC, bytes")
    w(f"  static constexpr std::uint16_t kDataId = 0x{m.data_id:04X};  // E2E data id, enters the CRC")
    w(f"  static constexpr std::size_t kCrcByte = {m.crc.start_bit // 8};")
    cyclic = "true" if m.cycle_ms > 0 else "false"
    w(f"  static constexpr bool kIsCyclic = {cyclic};")
    if m.cycle_ms > 0:
        w(f"  static constexpr std::chrono::milliseconds kCycleTime{{{m.cycle_ms}}};")
        w(f"  static constexpr std::chrono::milliseconds kTimeout{{{m.cycle_ms * TIMEOUT_CYCLES}}};")
    else:
        w("  static constexpr std::chrono::milliseconds kCycleTime{0};  // sent on event")
        w("  static constexpr std::chrono::milliseconds kTimeout{0};    // never times out")
    if mux is not None:
        page_type = cpp_type(mux)
        page_list = ", ".join(
            (f"{mux.name}::{identifier(dict(mux.values)[p])}" if mux.values else str(p)) for p in pages)
        w(f"  // Pages, in the order they are sent; each is one frame.")
        w(f"  static constexpr std::array<{page_type}, {len(pages)}> kPages{{{page_list}}};")
    w("")
    for s in m.payload_signals:
        page = "" if (s.mux_value is None or s.is_multiplexor) else f"page {s.mux_value}: "
        text = f"{page}{s.comment} {range_text(s)}." if kind_of(s) in ("double", "integer") else f"{page}{s.comment}"
        out.extend(wrap_comment(text, "  "))
        w(f"  {cpp_type(s)} {member_name(s)} = {default_value(s)};")
    w("};")
    w("")

    # Static checks of the wire layout.
    lay = f"layout::{ns}"
    w(f"static_assert({m.name}::kLength <= kMaxPayload);")
    for s in m.signals:
        w(f"static_assert(fits_in({lay}::{layout_name(s)}, {m.name}::kLength));")
    w(f"static_assert({lay}::{layout_name(m.crc)}.length == 8 && "
      f"occupied_bits({lay}::{layout_name(m.crc)}) == (std::uint64_t{{0xFF}} << (8 * {m.name}::kCrcByte)));")
    w(f"static_assert({lay}::{layout_name(m.counter)}.length == 4);")
    for page in (pages or [None]):
        group = [s for s in m.signals if s.mux_value is None or s.mux_value == page]
        names = ", ".join(f"{lay}::{layout_name(s)}" for s in group)
        w(f"static_assert(disjoint({{{names}}}));")
    w("")

    # Encode.
    w(f"// Writes {m.name}::kLength bytes (the rest of `out` is zeroed) and returns the DLC.")
    w(f"inline std::uint8_t encode(const {m.name}& message, std::uint8_t alive_counter,")
    w("                           std::span<std::uint8_t, 8> out) noexcept {")
    w("  for (auto& byte : out) byte = 0;")
    w(f"  const std::span<std::uint8_t> payload = out.first({m.name}::kLength);")
    w(f"  insert(payload, {lay}::{layout_name(m.counter)}, alive_counter % kAliveCounterModulo);")
    non_mux = [s for s in m.payload_signals if s.mux_value is None]
    for s in non_mux:
        emit_encode_signal(out, s, lay, "  ")
    if mux is not None:
        w(f"  switch (saturate(static_cast<std::int64_t>(message.{member_name(mux)}), "
          f"{mux.raw_min}, {mux.raw_max})) {{")
        for page in pages:
            w(f"    case {page}:")
            for s in m.payload_signals:
                if s.mux_value == page:
                    emit_encode_signal(out, s, lay, "      ")
            w("      break;")
        w("    default:  // not a page: header only; receivers reject it")
        w("      break;")
        w("  }")
    w(f"  payload[{m.name}::kCrcByte] = e2e_crc({m.name}::kDataId, payload, {m.name}::kCrcByte);")
    w(f"  return {m.name}::kLength;")
    w("}")
    w("")

    # Decode.
    w("namespace detail {")
    w(f"inline DecodeError decode_{ns}(std::span<const std::uint8_t> payload, E2eReceiverState* e2e,")
    w(f"                               {m.name}& out) noexcept {{")
    w(f"  if (payload.size() != {m.name}::kLength) return DecodeError::WrongLength;")
    w(f"  if (payload[{m.name}::kCrcByte] != e2e_crc({m.name}::kDataId, payload, {m.name}::kCrcByte)) {{")
    w("    return DecodeError::BadCrc;")
    w("  }")
    w(f"  const auto counter = static_cast<std::uint8_t>(extract(payload, {lay}::{layout_name(m.counter)}));")
    w("  if (e2e != nullptr && !e2e->accept(counter)) return DecodeError::BadCounter;")
    w(f"  {m.name} decoded = out;" + ("  // other pages keep their values" if mux is not None else ""))
    if mux is not None:
        w(f"  const std::int64_t page = extract(payload, {lay}::{layout_name(mux)});")
        w("  switch (page) {")
        for page in pages:
            w(f"    case {page}:")
        w("      break;")
        w("    default:")
        w("      return DecodeError::UnknownPage;")
        w("  }")
    for s in non_mux:
        emit_decode_signal(out, s, lay, "  ")
    if mux is not None:
        w("  switch (page) {")
        for page in pages:
            w(f"    case {page}: {{")
            for s in m.payload_signals:
                if s.mux_value == page:
                    emit_decode_signal(out, s, lay, "      ")
            w("      break;")
            w("    }")
        w("    default:")
        w("      break;")
        w("  }")
    w("  out = decoded;")
    w("  return DecodeError::None;")
    w("}")
    w("}  // namespace detail")
    w("")
    w("// Checks length, CRC, alive counter (updating `e2e`) and ranges.")
    w(f"[[nodiscard]] inline DecodeError decode(std::span<const std::uint8_t> payload, E2eReceiverState& e2e,")
    w(f"                                        {m.name}& out) noexcept {{")
    w(f"  return detail::decode_{ns}(payload, &e2e, out);")
    w("}")
    w("// Without counter check: for logs and tools that see frames out of sequence.")
    w(f"[[nodiscard]] inline DecodeError decode(std::span<const std::uint8_t> payload, {m.name}& out) noexcept {{")
    w(f"  return detail::decode_{ns}(payload, nullptr, out);")
    w("}")
    w("")


def emit_encode_signal(out: list[str], s: Signal, lay: str, indent: str) -> None:
    kind = kind_of(s)
    member = f"message.{member_name(s)}"
    target = f"payload, {lay}::{layout_name(s)}"
    if kind == "bool":
        value = f"{member} ? 1 : 0"
    elif kind in ("enum", "integer"):
        value = f"saturate(static_cast<std::int64_t>({member}), {s.raw_min}, {s.raw_max})"
    else:
        value = (f"raw_from_physical({member}, {cpp_double(s.factor)}, {cpp_double(s.offset)}, "
                 f"{s.raw_min}, {s.raw_max})")
    out.append(f"{indent}insert({target}, {value});")


def emit_decode_signal(out: list[str], s: Signal, lay: str, indent: str) -> None:
    w = out.append
    kind = kind_of(s)
    raw = f"raw_{snake(s.name)}"
    w(f"{indent}const std::int64_t {raw} = extract(payload, {lay}::{layout_name(s)});")
    if kind == "enum":
        cond = " && ".join(f"{raw} != {v}" for v, _ in s.values)
        w(f"{indent}if ({cond}) return DecodeError::OutOfRange;")
    else:
        w(f"{indent}if ({raw} < {s.raw_min} || {raw} > {s.raw_max}) return DecodeError::OutOfRange;")
    target = f"decoded.{member_name(s)}"
    if kind == "enum":
        w(f"{indent}{target} = static_cast<{s.name}>({raw});")
    elif kind == "bool":
        w(f"{indent}{target} = {raw} != 0;")
    elif kind == "integer":
        w(f"{indent}{target} = static_cast<{cpp_type(s)}>({raw});")
    else:
        w(f"{indent}{target} = physical_from_raw({raw}, {cpp_double(s.factor)}, {cpp_double(s.offset)});")


# --------------------------------------------------------------------------
# Markdown

def emit_markdown(db: Database) -> str:
    out: list[str] = []
    w = out.append
    w("| Message | ID | DLC | Sender | Receivers | Cycle | E2E data id | Description |")
    w("|---|---|---|---|---|---|---|---|")
    for m in db.messages:
        receivers = sorted({r for s in m.signals for r in s.receivers})
        cycle = f"{m.cycle_ms} ms" if m.cycle_ms else "event"
        w(f"| {m.name} | 0x{m.frame_id:03X} | {m.length} | {m.sender} | {', '.join(receivers)} | {cycle} "
          f"| 0x{m.data_id:04X} | {md(m.comment)} |")
    for m in db.messages:
        w("")
        w(f"### {m.name} (0x{m.frame_id:03X})")
        w("")
        w("| Signal | Page | Start\\|Len | Order | Type | Factor | Offset | Min | Max | Unit | Values | Description |")
        w("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for s in m.signals:
            page = "M" if s.is_multiplexor else ("" if s.mux_value is None else str(s.mux_value))
            order = "Intel" if s.intel else "Motorola"
            sign = "signed" if s.signed else "unsigned"
            values = ", ".join(f"{v}={t}" for v, t in s.values)
            w(f"| {s.name} | {page} | {s.start_bit}\\|{s.length} | {order} | {sign} | {fmt(s.factor)} "
              f"| {fmt(s.offset)} | {fmt(s.minimum)} | {fmt(s.maximum)} | {s.unit} | {values} | {md(s.comment)} |")
    return "\n".join(out) + "\n"


def md(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def readme_with_table(readme: str, table: str) -> str:
    begin, end = readme.find(README_BEGIN), readme.find(README_END)
    if begin < 0 or end < begin:
        raise DbcError("README has no generated-section markers")
    return readme[: begin + len(README_BEGIN)] + "\n" + table + readme[end:]


# --------------------------------------------------------------------------

def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dbc", type=Path)
    ap.add_argument("--header", type=Path, help="write the C++ header here")
    ap.add_argument("--markdown", help="write the Markdown table here ('-' for stdout)")
    ap.add_argument("--node", default="MARKLOOP", help="the ECU the code is generated for")
    ap.add_argument("--update-readme", type=Path, help="rewrite the generated table in this README")
    ap.add_argument("--check-readme", type=Path, help="fail if this README's table is stale")
    args = ap.parse_args()
    try:
        db = parse_dbc(args.dbc.read_text(encoding="utf-8"))
        if args.header:
            write_if_changed(args.header, emit_header(db, f"dbc/{args.dbc.name}", args.node))
        table = emit_markdown(db)
        if args.markdown == "-":
            sys.stdout.write(table)
        elif args.markdown:
            write_if_changed(Path(args.markdown), table)
        if args.update_readme:
            text = args.update_readme.read_text(encoding="utf-8")
            write_if_changed(args.update_readme, readme_with_table(text, table))
        if args.check_readme:
            text = args.check_readme.read_text(encoding="utf-8")
            if readme_with_table(text, table) != text:
                print(f"{args.check_readme} is stale: run dbc/generate.py {args.dbc} "
                      f"--update-readme {args.check_readme}", file=sys.stderr)
                return 1
    except DbcError as error:
        print(f"{args.dbc}: error: {error}", file=sys.stderr)
        return 1
    return 0


def write_if_changed(path: Path, text: str) -> None:
    # Unchanged output keeps its timestamp, so nothing recompiles needlessly.
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
