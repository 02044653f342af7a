"""The Colossus protocol against the layouts of Navtech's SDK (IASDK ``cpp_17`` and its Python
client): bytes written field by field from the SDK's offsets, not by the encoder under test."""

from __future__ import annotations

import numpy as np
import pytest

from impala_radar.datasets.common import counts_to_power
from impala_radar.navtech.convert import beam_power, counts_of_power
from impala_radar.navtech.protocol import (
    HEADER_BYTES,
    MAX_PAYLOAD_BYTES,
    SIGNATURE,
    Configuration,
    FftData,
    MessageType,
    ProtocolError,
    StreamDecoder,
    decode_header,
    encode_message,
)

# the SDK's Signature::signature (Colossus_network_message.cpp)
SDK_SIGNATURE = bytes.fromhex("00 01 03 03 07 07 0F 0F 1F 1F 3F 3F 7F 7F FE FE")


def sdk_header(msg_type: int, size: int, version: int = 1) -> bytes:
    """The SDK's 22-byte header: signature, version, type, payload size (uint32, htonl)."""
    return SDK_SIGNATURE + bytes([version, msg_type]) + size.to_bytes(4, "big")


def test_constants_are_the_sdks():
    assert SIGNATURE == SDK_SIGNATURE and HEADER_BYTES == 22 and MAX_PAYLOAD_BYTES == 1_000_000
    types = {"KEEP_ALIVE": 1, "CONFIGURATION": 10, "CONFIGURATION_REQUEST": 20, "START_FFT_DATA": 21,
             "STOP_FFT_DATA": 22, "FFT_DATA": 30, "HIGH_PRECISION_FFT_DATA": 31, "NAVIGATION_DATA": 123}
    assert {t.name: int(t) for t in MessageType} == types


def test_header_only_messages_as_the_sdk_python_client_sends_them():
    # ReadOneRotationOfFFTData.py: signature + version + type (1 byte each) + 4 zero bytes
    for t in (20, 21, 22, 1):
        assert encode_message(t) == SDK_SIGNATURE + bytes([1, t]) + b"\0\0\0\0"
    assert decode_header(sdk_header(31, 3782)) == (1, 31, 3782)


def test_configuration_layout():
    # azimuth_samples, bin_size (0.1 mm), range_in_bins, encoder_size, rotation_speed (mHz), packet_rate: u16 BE;
    # range_gain, range_offset: IEEE float32 BE; then the protocol buffer
    payload = (b"\x01\x90" + b"\x01\xb6" + b"\x0e\xb8" + b"\x15\xe0" + b"\x0f\xa0" + b"\x06\x40"
               + bytes.fromhex("3f800000") + bytes.fromhex("bf000000") + b"\x08\x96\x01")
    c = Configuration.decode(payload)
    assert (c.azimuth_samples, c.bin_size, c.range_in_bins, c.encoder_size, c.rotation_speed_mhz, c.packet_rate) \
        == (400, 438, 3768, 5600, 4000, 1600)
    assert (c.range_gain, c.range_offset_m, c.protobuf) == (1.0, -0.5, b"\x08\x96\x01")
    assert c.range_per_bin_m == pytest.approx(0.0438, rel=1e-15) and c.rotation_hz == 4.0
    assert c.encode() == payload
    msg = encode_message(MessageType.CONFIGURATION, payload)
    assert msg[:22] == sdk_header(10, len(payload))
    with pytest.raises(ProtocolError, match="configuration message: 19 payload bytes"):
        Configuration.decode(payload[:19])


def test_fft_data_layout_8_and_16_bit():
    seconds, split = 1_547_131_046, 123_456_789
    # fft_data_offset (14), sweep_counter, azimuth: u16 BE; seconds, split_seconds: u32 LE (the SDK's Python client)
    head = (14).to_bytes(2, "big") + (0x1234).to_bytes(2, "big") + (13).to_bytes(2, "big") \
        + seconds.to_bytes(4, "little") + split.to_bytes(4, "little")
    f = FftData.decode(head + bytes([0, 1, 255]), high_precision=False)
    assert (f.sweep_counter, f.azimuth, f.seconds, f.split_seconds) == (0x1234, 13, seconds, split)
    assert f.device_ns == seconds * 10**9 + split and f.type == 30
    assert f.values().tolist() == [0, 1, 255]
    assert f.encode() == head + bytes([0, 1, 255])
    g = FftData.decode(head + bytes([0x01, 0x02, 0xFF, 0xFF]), high_precision=True)
    assert g.values().dtype == np.uint16 and g.values().tolist() == [0x0102, 0xFFFF] and g.type == 31
    # the samples start at fft_data_offset, wherever the radar puts it
    later = (16).to_bytes(2, "big") + head[2:] + b"\xaa\xbb" + bytes([7])
    assert FftData.decode(later, False).values().tolist() == [7]
    with pytest.raises(ProtocolError, match="fft_data_offset 99"):
        FftData.decode((99).to_bytes(2, "big") + head[2:], False)
    with pytest.raises(ProtocolError, match="odd number"):
        FftData.decode(head + b"\x01", True)
    with pytest.raises(ProtocolError, match="split_seconds"):
        FftData.decode(head[:10] + (10**9).to_bytes(4, "little"), False)


def _stream() -> tuple[bytes, list[tuple[int, bytes]]]:
    parts = [(10, bytes(range(20)) + b"pb"), (1, b""), (30, bytes(14) + bytes(range(200))), (31, bytes(14 + 6))]
    return b"".join(sdk_header(t, len(p)) + p for t, p in parts), parts


def test_decoder_whole_messages_from_any_chunking():
    data, parts = _stream()
    rng = np.random.default_rng(4)
    for chunking in ("bytes", "random", "whole"):
        dec, got = StreamDecoder(), []
        if chunking == "bytes":
            cuts = list(range(len(data) + 1))
        elif chunking == "random":
            cuts = [0, *sorted(rng.choice(np.arange(1, len(data)), 7, replace=False).tolist()), len(data)]
        else:
            cuts = [0, len(data)]
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            got += dec.feed(data[a:b])
        assert [(m.type, m.payload) for m in got] == parts, chunking
        assert dec.buffered == 0 and dec.offset == len(data)


def test_decoder_refuses_a_bad_signature_with_its_position():
    data, _ = _stream()
    first = 22 + 22 + 22  # after the configuration (22-byte payload) and the keep-alive
    bad = data[:first] + b"\x00" * 22 + data[first:]
    dec = StreamDecoder()
    # the two whole messages before the bad bytes come out; the error is kept, raised next
    assert [m.type for m in dec.feed(bad)] == [10, 1]
    assert dec.error is not None and f"bad signature at byte {first}: 00 00 00" in str(dec.error)
    with pytest.raises(ProtocolError, match=f"bad signature at byte {first}"):
        dec.feed(b"")
    with pytest.raises(ProtocolError, match="bad signature at byte 0"):
        StreamDecoder().feed(bad[first:])


def test_decoder_bounds_the_payload_before_buffering_it():
    dec = StreamDecoder(max_payload_bytes=4096)
    with pytest.raises(ProtocolError, match=r"fft_data \(30\) message at byte 0: payload of 4096 bytes, over the "
                       r"bound of 4095 bytes"):
        dec.feed(sdk_header(30, 4096))
    dec = StreamDecoder()
    with pytest.raises(ProtocolError, match="type 200 message at byte 0: payload of 4294967295 bytes"):
        dec.feed(sdk_header(200, 0xFFFFFFFF) + bytes(1000))
    assert dec.buffered <= 22 + 1000


def test_decoder_refuses_another_version():
    with pytest.raises(ProtocolError, match="version 2, expected 1"):
        StreamDecoder().feed(sdk_header(1, 0, version=2))


def test_samples_and_powers_round_trip_exactly():
    """The emulator's inverse gives every 8-bit count and 16-bit value back from the power the
    driver makes of it; the 8-bit power is the readers' (count / 255 through counts_to_power)."""
    for high_precision, top in ((False, 255), (True, 65535)):
        v = np.arange(top + 1)
        p = beam_power(v, 0.5, high_precision)
        back, clipped = counts_of_power(p, 0.5, high_precision)
        assert np.array_equal(back, v) and clipped == 0
    assert np.array_equal(beam_power(np.arange(256), 0.5, False),
                          counts_to_power(np.arange(256) / 255.0, 0.5))
    # 16-bit value 256 c is the 8-bit count c
    assert np.array_equal(beam_power(np.arange(256) * 256, 0.5, True), beam_power(np.arange(256), 0.5, False))
    back, clipped = counts_of_power(np.array([0.5, np.nan, np.inf, 1.0], np.float32), 0.5, False)
    assert back.tolist() == [0, 0, 255, 0] and clipped == 3
