#!/usr/bin/env python3
"""The generator parses the real DBC and refuses broken ones loudly.
Usage: test_generator.py GENERATOR DBC"""

import importlib.util
import sys
import unittest

GENERATOR, DBC = sys.argv[1], sys.argv[2]
spec = importlib.util.spec_from_file_location("generate", GENERATOR)
generate = importlib.util.module_from_spec(spec)
sys.modules["generate"] = generate  # dataclasses look the module up by name
spec.loader.exec_module(generate)
with open(DBC, encoding="utf-8") as f:
    TEXT = f.read()


def edited(old, new, count=1):
    assert TEXT.count(old) >= count, f"test edit not applicable: {old!r}"
    return TEXT.replace(old, new)


class RealDbc(unittest.TestCase):
    def setUp(self):
        self.db = generate.parse_dbc(TEXT)

    def test_messages_and_attributes(self):
        by_name = {m.name: m for m in self.db.messages}
        self.assertEqual(sorted(by_name), ["Command", "LoopDetection", "Status", "VehicleOdometry"])
        self.assertEqual(by_name["VehicleOdometry"].cycle_ms, 20)
        self.assertEqual(by_name["Status"].cycle_ms, 100)
        self.assertEqual(by_name["Command"].cycle_ms, 0)
        self.assertEqual(by_name["LoopDetection"].multiplexor.name, "LoopPage")
        self.assertEqual(self.db.nodes, ["MARKLOOP", "GATEWAY", "SLAM"])
        self.assertIn("0x1D", self.db.comment)

    def test_signals(self):
        loop = next(m for m in self.db.messages if m.name == "LoopDetection")
        query = loop.signal("QueryFrame")
        self.assertEqual((query.start_bit, query.length, query.intel, query.mux_value), (24, 32, True, 0))
        odo = next(m for m in self.db.messages if m.name == "VehicleOdometry")
        speed = odo.signal("WheelSpeed")
        self.assertFalse(speed.intel)
        self.assertTrue(speed.signed)
        self.assertEqual((speed.raw_min, speed.raw_max), (-10000, 10000))
        # Motorola start 23, 16 bits: byte 2 (bits 16..23) and byte 3 (24..31).
        self.assertEqual(generate.occupied_bits(speed), set(range(16, 32)))
        self.assertEqual(generate.occupied_bits(odo.signal("OdoAliveCounter")), {8, 9, 10, 11})

    def test_outputs_mention_everything(self):
        header = generate.emit_header(self.db, "dbc/markloop.dbc", "MARKLOOP")
        table = generate.emit_markdown(self.db)
        for m in self.db.messages:
            self.assertIn(f"struct {m.name} {{", header)
            for s in m.signals:
                self.assertIn(f"| {s.name} |", table)
        self.assertIn("std::uint32_t query_frame", header)
        self.assertNotIn("new ", header)
        self.assertNotIn("throw", header)

    def test_multiline_comment_and_escapes(self):
        db = generate.parse_dbc(edited('CM_ BO_ 416 "Service command to markloop, sent on demand.";',
                                       'CM_ BO_ 416 "Service command\nover two lines, \\"quoted\\".";'))
        command = next(m for m in db.messages if m.name == "Command")
        self.assertEqual(command.comment, 'Service command\nover two lines, "quoted".')


class BrokenDbc(unittest.TestCase):
    def rejects(self, text, message_part):
        with self.assertRaises(generate.DbcError) as caught:
            generate.parse_dbc(text)
        self.assertIn(message_part, str(caught.exception))

    def test_overlap(self):
        self.rejects(edited("SG_ YawRate : 39|16@0-", "SG_ YawRate : 31|16@0-"), "overlaps")

    def test_overlap_within_a_page(self):
        self.rejects(edited("SG_ PoseDy m4 : 40|16@1-", "SG_ PoseDy m4 : 32|16@1-"), "overlaps")

    def test_min_off_grid(self):
        self.rejects(edited("(0.004,0) [0|1]", "(0.004,0) [0|1.001]"), "not a multiple")

    def test_range_beyond_bits(self):
        self.rejects(edited("(0.01,0) [-100|100]", "(0.01,0) [-400|400]"), "the bits hold")

    def test_missing_crc(self):
        self.rejects(TEXT.replace("OdoCrc", "OdoCheck"), "Crc")

    def test_crc_not_byte_aligned(self):
        self.rejects(edited("SG_ CmdCrc : 0|8@1+", "SG_ CmdCrc : 1|8@1+").replace(
            "SG_ CmdAliveCounter : 8|4@1+", "SG_ CmdAliveCounter : 10|4@1+"), "whole unsigned byte")

    def test_duplicate_data_id(self):
        self.rejects(edited('BA_ "E2EDataID" BO_ 416 20738;', 'BA_ "E2EDataID" BO_ 416 20737;'), "E2EDataID")

    def test_signal_beyond_dlc(self):
        self.rejects(edited("BO_ 416 Command: 4 GATEWAY", "BO_ 416 Command: 2 GATEWAY"), "does not fit")

    def test_extended_id(self):
        self.rejects(TEXT.replace(" 416 ", " 4096 "), "11-bit")

    def test_cyclic_without_cycle_time(self):
        self.rejects(edited('BA_ "GenMsgCycleTime" BO_ 288 20;\n', ""), "cyclic")

    def test_missing_comment(self):
        self.rejects(edited('CM_ SG_ 416 CommandCode "What markloop shall do; 0 is deliberately undefined so '
                            'an all-zero frame is never a command.";\n', ""), "no comment")

    def test_bad_byte_order(self):
        self.rejects(edited("SG_ CommandCode : 16|8@1+", "SG_ CommandCode : 16|8@2+"), "@0 or @1")

    def test_unsupported_keyword(self):
        self.rejects(TEXT + "\nSIG_VALTYPE_ 416 CommandCode : 1;\n", "unsupported")

    def test_value_outside_range(self):
        self.rejects(edited('VAL_ 416 CommandCode 1 "ResetDatabase" 2 "SaveMap" ;',
                            'VAL_ 416 CommandCode 1 "ResetDatabase" 2 "SaveMap" 3 "Reboot" ;'), "outside")

    def test_page_without_value_name(self):
        self.rejects(edited('VAL_ 688 StatusPage 0 "Processing" 1 "Timing" 2 "Database" 3 "Perception" 4 "Odometry" ;',
                            'VAL_ 688 StatusPage 0 "Processing" 1 "Timing" 2 "Database" ;'), "exactly the pages")

    def test_unterminated_statement(self):
        self.rejects(edited('BA_ "DBName" "markloop";', 'BA_ "DBName" "markloop"'), "expected")


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0], "-v"])
