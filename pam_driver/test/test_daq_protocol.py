"""The DAQ serial protocol without ROS: framing, CRC, round trips, resynchronisation."""

from __future__ import annotations

import random

import pytest

from pam_driver import daq_protocol as proto


def test_crc_check_value():
    assert proto.crc16(b'123456789') == 0x29B1   # CRC-16/CCITT-FALSE


def test_round_trip_every_frame_type():
    info = proto.DeviceInfo(1, 0, 1000, 12, 12, proto.FLAG_ENCODER | proto.FLAG_TORQUE)
    sample = proto.Sample(123456, 4095, 0, -40000, 2048, 1)
    stream = (proto.hello(1) + proto.hello_ack(2, info) + proto.command(3, 4095, 17)
              + proto.heartbeat(4) + proto.sample(5, sample)
              + proto.device_heartbeat(6, 10, 2, 1, 0))
    d = proto.Decoder()
    frames = d.feed(stream)
    assert [f.type for f in frames] == [proto.HELLO, proto.HELLO_ACK, proto.COMMAND,
                                        proto.HEARTBEAT, proto.SAMPLE, proto.DEVICE_HEARTBEAT]
    assert [f.seq for f in frames] == [1, 2, 3, 4, 5, 6]
    assert frames[0].fields() == (proto.PROTOCOL_MAJOR, proto.PROTOCOL_MINOR)
    assert proto.parse_hello_ack(frames[1]) == info
    assert frames[2].fields() == (4095, 17)
    assert frames[3].fields() == ()
    assert proto.parse_sample(frames[4]) == sample
    assert frames[5].fields() == (10, 2, 1, 0)
    assert d.garbage_bytes == 0 and d.crc_errors == 0


def test_byte_by_byte_feeding():
    frame = proto.sample(9, proto.Sample(1, 2, 3, 4, 5))
    d = proto.Decoder()
    got = []
    for b in frame * 3:
        got += d.feed(bytes([b]))
    assert len(got) == 3 and d.garbage_bytes == 0


def test_garbage_and_crc_errors_resynchronise():
    rng = random.Random(1)
    frames = [proto.sample(i, proto.Sample(i, i, i, i, i)) for i in range(200)]
    stream = bytearray()
    corrupted = 0
    for i, f in enumerate(frames):
        if i % 7 == 3:
            stream += bytes(rng.randrange(256) for _ in range(rng.randint(1, 20)))
        start = len(stream)
        stream += f
        if i % 11 == 5:
            stream[rng.randrange(start + proto.HEADER_SIZE, len(stream))] ^= 0x10
            corrupted += 1
    d = proto.Decoder()
    got = []
    for i in range(0, len(stream), 13):
        got += d.feed(bytes(stream[i:i + 13]))
    seqs = [f.seq for f in got]
    expected = [i for i in range(200) if i % 11 != 5]
    assert seqs == expected
    assert d.crc_errors >= corrupted
    assert d.garbage_bytes > 0
    tracker = proto.SequenceTracker()
    for s in seqs:
        tracker.update(s)
    assert tracker.lost == corrupted


def test_false_sync_does_not_hide_a_frame():
    frame = proto.heartbeat(7)
    d = proto.Decoder()
    got = d.feed(proto.SYNC + bytes([0x80, 0, 0, 30]) + frame)   # a header promising 30 bytes
    got += d.feed(proto.heartbeat(8) * 5)
    assert [f.seq for f in got][:2] == [7, 8]
    assert d.crc_errors >= 1


def test_oversized_length_is_rejected():
    d = proto.Decoder()
    got = d.feed(proto.SYNC + bytes([0x80, 0, 0, 200]) + proto.heartbeat(1))
    assert [f.seq for f in got] == [1] and d.crc_errors == 1


def test_sequence_wraps_and_bad_payload():
    t = proto.SequenceTracker()
    for s in (65534, 65535, 0, 3):
        t.update(s)
    assert t.lost == 2 and t.gaps == 1
    with pytest.raises(proto.ProtocolError):
        proto.Frame(proto.SAMPLE, 0, b'\x00').fields()
    with pytest.raises(proto.ProtocolError):
        proto.Frame(0x42, 0, b'').fields()


def test_fields_a_later_minor_version_appends_are_ignored():
    """PROTOCOL.md: a minor version adds fields at the end of a payload only."""
    sample = proto.Sample(7, 1, 2, -3, 4, proto.STATUS_VENTED)
    frame = next(iter(proto.Decoder().feed(proto.sample(0, sample))))
    longer = proto.Frame(frame.type, frame.seq, frame.payload + b'\x01\x02\x03')
    assert proto.parse_sample(longer) == sample
    info = proto.DeviceInfo(1, 7, 1000, 12, 12, 0)
    ack = next(iter(proto.Decoder().feed(proto.hello_ack(0, info))))
    assert proto.parse_hello_ack(proto.Frame(ack.type, 0, ack.payload + b'\x00')) == info
    assert proto.Frame(proto.HEARTBEAT, 0, b'\x09').fields() == ()


def test_tick_counter_counts_device_samples_and_never_goes_back():
    ticks = proto.TickCounter()
    assert [ticks.update(t) for t in (500, 501, 504, 505)] == [1, 2, 5, 6]   # 2 lost on the line
    ticks = proto.TickCounter()
    assert [ticks.update(t) for t in (0xFFFFFFFE, 0xFFFFFFFF, 0, 2)] == [1, 2, 3, 5]   # wraps
    assert ticks.restarts == 0
    assert ticks.update(1) == 6 and ticks.restarts == 1       # behind: the device restarted
    assert ticks.update(1) == 7 and ticks.restarts == 2       # the same tick again: too
    assert ticks.update(2) == 8


def test_board_vents_from_the_sample_status_and_the_heartbeat():
    vents = proto.BoardVents()
    for status in (0, 1, 1, 0, 0, 1, 0):          # two vents seen in the samples
        vents.on_sample(status)
    assert (vents.count, vents.vented) == (2, False)
    vents.on_heartbeat(40)                        # 38 before this host: not counted
    assert vents.count == 2
    vents.on_heartbeat(43)                        # 3 more, of which the samples showed none
    assert vents.count == 5
    vents.on_sample(proto.STATUS_VENTED)
    assert vents.vented and vents.count == 5      # the heartbeat counted it already
    vents.on_sample(0)
    vents.on_sample(1)
    assert vents.count == 5 and vents.edges == 4
    vents.on_sample(0)
    vents.on_sample(1)
    assert vents.count == 5                       # edges 5, trips 5
    vents.on_sample(0)
    vents.on_sample(1)
    assert vents.count == 6                       # edges 6
    vents.on_heartbeat(2)                         # the device restarted: its counter begins again
    vents.on_heartbeat(3)
    assert vents.trips == 6 and vents.count == 6


# ---- the optional supply-pressure channel (1.1) ------------------------------------------------
def _frame_1_0(seq: int, payload: bytes) -> bytes:
    """A frame exactly as PROTOCOL.md 1.0 lays it out, built by hand."""
    body = bytes([proto.SAMPLE]) + seq.to_bytes(2, 'little') + bytes([len(payload)]) + payload
    return b'\xa5\x5a' + body + proto.crc16(body).to_bytes(2, 'little')


def test_a_board_without_the_supply_channel_sends_the_frames_of_1_0():
    payload = ((123456).to_bytes(4, 'little') + (4095).to_bytes(2, 'little')
               + (17).to_bytes(2, 'little') + (-40000).to_bytes(4, 'little', signed=True)
               + (2048).to_bytes(2, 'little') + b'\x01')
    old = _frame_1_0(7, payload)
    assert len(payload) == 15
    sample = proto.Sample(123456, 4095, 17, -40000, 2048, 1, adc_supply=None)
    assert proto.sample(7, sample) == old, 'byte for byte as 1.0'
    (frame,) = proto.Decoder().feed(old)
    # read by a host that knows the channel, from a board that does not report it (or does:
    # a frame cut short before the field) -> no supply reading, every other field
    assert proto.parse_sample(frame) == sample
    assert proto.parse_sample(frame, supply=True) == sample


def test_supply_channel_round_trip_and_what_a_1_0_host_reads():
    info = proto.DeviceInfo(1, 1, 1000, 12, 12,
                            proto.FLAG_ENCODER | proto.FLAG_TORQUE | proto.FLAG_SUPPLY)
    plain = proto.DeviceInfo(1, 1, 1000, 12, 12, proto.FLAG_ENCODER | proto.FLAG_TORQUE)
    sample = proto.Sample(99, 1000, 2000, 5, 2048, 0, adc_supply=3210)
    d = proto.Decoder()
    ack, ack_plain, frame = d.feed(proto.hello_ack(1, info) + proto.hello_ack(2, plain)
                                   + proto.sample(3, sample))
    assert proto.parse_hello_ack(ack).has_supply and not proto.parse_hello_ack(ack_plain).has_supply
    assert len(frame.payload) == 17
    assert frame.payload[15:] == (3210).to_bytes(2, 'little'), 'the field at offset 15, u16 LE'
    assert proto.parse_sample(frame, supply=True) == sample
    # a host that does not read the channel (1.0, or a device not reporting it) gets the rest
    assert proto.parse_sample(frame) == proto.Sample(99, 1000, 2000, 5, 2048, 0)
    assert frame.fields() == (99, 1000, 2000, 5, 2048, 0), 'the 1.0 fields, the rest ignored'
    assert proto.PROTOCOL_MINOR >= 1


def test_arm_frame_and_the_devices_that_take_it():
    """ARM (1.2): type 0x04, no payload, the board's own encoding (firmware/core); only a device
    of major 1 announcing minor 2 or later takes it."""
    frame = proto.arm(7)
    assert frame == proto.encode_frame(0x04, 7) and len(frame) == proto.OVERHEAD
    decoded, = proto.Decoder().feed(frame)
    assert (decoded.type, decoded.seq, decoded.name, decoded.fields()) == (proto.ARM, 7, 'ARM', ())

    def info(major, minor):
        return proto.DeviceInfo(major, minor, 1000, 12, 12, 0)
    assert [info(1, m).has_arm for m in (0, 1, 2, 3)] == [False, False, True, True]
    assert not info(2, 2).has_arm
