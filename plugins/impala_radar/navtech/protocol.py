"""Navtech "Colossus" TCP protocol: message framing, configuration, FFT data, a streaming decoder.

Checked against Navtech's public IASDK (MIT licence), as mirrored in
``norlab-ulaval/iasdk_navtech_radar`` (commit 0f208fdd, the SDK's 2023 ``cpp_17`` tree):
``cpp_17/src/network/protocol/Colossus/protocol/Colossus_network_message.{h,cpp}`` (header,
signature, version, payload bound), ``Colossus_message_types.h`` (type numbers),
``Colossus_messages.h`` (``Configuration`` and ``FFT_data`` overlays) and
``pythonexamples/ReadOneRotationOfFFTData.py`` (the Python client). Learnt from, no code copied.

Every message is a 22-byte header and a payload:

=======  =====  ==========================================================================
offset   bytes  field
=======  =====  ==========================================================================
0        16     signature ``00 01 03 03 07 07 0F 0F 1F 1F 3F 3F 7F 7F FE FE``
16       1      version (1: the SDK's ``is_valid()`` refuses any other)
17       1      type (:class:`MessageType`)
18       4      payload size, uint32 big-endian (the SDK refuses 1 000 000 bytes or more)
=======  =====  ==========================================================================

Configuration (type 10) payload, big-endian: ``azimuth_samples u16, bin_size u16`` (tenths of
a millimetre), ``range_in_bins u16, encoder_size u16, rotation_speed u16`` (mHz),
``packet_rate u16`` (azimuths per second), ``range_gain f32, range_offset f32`` (metres), then a
protocol buffer (carried here as opaque bytes). FFT data (type 30: 8-bit samples; 31: 16-bit
"high precision" samples, big-endian): ``fft_data_offset u16`` (where the samples start in the
payload: 14), ``sweep_counter u16, azimuth u16`` (encoder count) big-endian, then
``seconds u32, split_seconds u32`` (the device time, ns within the second) **little-endian**,
then the samples.

Where the issue's facts needed care: the SDK is not self-consistent on the time fields. Its
C++ ``FFT_data`` setter writes them with ``htonl`` (big-endian) but its getter returns them
raw, without ``ntohl`` (host order, little-endian on the radar's and clients' x86/ARM), and its
Python client reads them little-endian: the radar sends them little-endian, as the issue says;
this module writes and reads little-endian. The Python client reads 16-bit samples big-endian
(with a stride bug, one byte per sample); big-endian is what is implemented here. Everything
else in the issue matched the SDK.

Framing errors: a bad signature or an unknown version is a :class:`ProtocolError`, never a
resync. TCP delivers the radar's bytes in order and complete, so a bad signature means the peer
does not speak the protocol or the stream is corrupt; scanning forward for the next signature
could frame a message on sample bytes (FFT data are arbitrary bytes and may hold the
signature) and deliver garbage as data. The driver reconnects instead: a new connection starts
on a message boundary, with the configuration first.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

__all__ = ["SIGNATURE", "VERSION", "HEADER_BYTES", "DEFAULT_PORT", "MAX_PAYLOAD_BYTES", "FFT_HEADER_BYTES",
           "MessageType", "ProtocolError", "Message", "Configuration", "FftData", "StreamDecoder",
           "encode_message", "decode_header"]

SIGNATURE = bytes((0x00, 0x01, 0x03, 0x03, 0x07, 0x07, 0x0F, 0x0F, 0x1F, 0x1F, 0x3F, 0x3F, 0x7F, 0x7F, 0xFE, 0xFE))
VERSION = 1
HEADER_BYTES = 22
DEFAULT_PORT = 6317
#: the SDK's bound: a payload of this size or more is invalid (``payload_size() < largest_payload``)
MAX_PAYLOAD_BYTES = 1_000_000
_CONFIG = struct.Struct(">6H2f")  # 20 bytes, then the protocol buffer
_FFT = struct.Struct(">3H")  # data offset, sweep counter, azimuth
_TIME = struct.Struct("<2I")  # seconds, split seconds (ns)
FFT_HEADER_BYTES = _FFT.size + _TIME.size  # 14


class MessageType(IntEnum):
    """Colossus message types (the SDK's ``Colossus_message_types.h``; the ones used here)."""

    KEEP_ALIVE = 1
    CONFIGURATION = 10
    CONFIGURATION_REQUEST = 20
    START_FFT_DATA = 21
    STOP_FFT_DATA = 22
    FFT_DATA = 30
    HIGH_PRECISION_FFT_DATA = 31
    NAVIGATION_DATA = 123


def _type_name(t: int) -> str:
    try:
        return f"{MessageType(t).name.lower()} ({t})"
    except ValueError:
        return f"type {t}"


class ProtocolError(ValueError):
    """Bytes that are no Colossus message; one line saying what and where."""


@dataclass(frozen=True)
class Message:
    """One framed message: its type (int, see :class:`MessageType`) and payload bytes."""

    type: int
    payload: bytes
    version: int = VERSION


def encode_message(msg_type: int, payload: bytes = b"", version: int = VERSION) -> bytes:
    """Header + payload of one message."""
    return SIGNATURE + struct.pack(">BBI", version, int(msg_type), len(payload)) + bytes(payload)


def decode_header(header: bytes, max_payload_bytes: int = MAX_PAYLOAD_BYTES, offset: int = 0) -> tuple[int, int, int]:
    """``(version, type, payload size)`` of a 22-byte header; a :class:`ProtocolError` for a
    bad signature, another version, or a payload size at or over ``max_payload_bytes``
    (``offset``: the header's position in the stream, for the error line)."""
    if len(header) < HEADER_BYTES:
        raise ProtocolError(f"header at byte {offset}: {len(header)} bytes, expected {HEADER_BYTES}")
    if header[:16] != SIGNATURE:
        raise ProtocolError(f"bad signature at byte {offset}: {header[:16].hex(' ')} (expected "
                            f"{SIGNATURE.hex(' ')}): not a Navtech Colossus stream, or a corrupt one")
    version, msg_type, size = struct.unpack_from(">BBI", header, 16)
    if version != VERSION:
        raise ProtocolError(f"message at byte {offset}: version {version}, expected {VERSION}")
    if size >= max_payload_bytes:
        raise ProtocolError(f"{_type_name(msg_type)} message at byte {offset}: payload of {size} bytes, "
                            f"over the bound of {max_payload_bytes - 1} bytes")
    return version, msg_type, size


@dataclass(frozen=True)
class Configuration:
    """The radar's configuration (type 10). ``bin_size`` in tenths of a millimetre,
    ``rotation_speed_mhz`` in mHz, ``range_offset_m`` in metres; ``protobuf`` the opaque tail."""

    azimuth_samples: int
    bin_size: int
    range_in_bins: int
    encoder_size: int
    rotation_speed_mhz: int
    packet_rate: int
    range_gain: float = 1.0
    range_offset_m: float = 0.0
    protobuf: bytes = b""

    @property
    def range_per_bin_m(self) -> float:
        """Range per bin: ``bin_size`` (0.1 mm) x ``range_gain``."""
        return self.bin_size / 10_000.0 * float(self.range_gain)

    @property
    def rotation_hz(self) -> float:
        return self.rotation_speed_mhz / 1000.0

    def encode(self) -> bytes:
        """The payload (20 bytes + the protocol buffer)."""
        for name in ("azimuth_samples", "bin_size", "range_in_bins", "encoder_size", "rotation_speed_mhz",
                     "packet_rate"):
            v = getattr(self, name)
            if not 0 <= v <= 0xFFFF:
                raise ProtocolError(f"configuration: {name} {v} does not fit 16 bits")
        return _CONFIG.pack(self.azimuth_samples, self.bin_size, self.range_in_bins, self.encoder_size,
                            self.rotation_speed_mhz, self.packet_rate, self.range_gain,
                            self.range_offset_m) + self.protobuf

    @classmethod
    def decode(cls, payload: bytes) -> Configuration:
        if len(payload) < _CONFIG.size:
            raise ProtocolError(f"configuration message: {len(payload)} payload bytes, expected at least "
                                f"{_CONFIG.size}")
        f = _CONFIG.unpack_from(payload)
        return cls(*f[:6], float(f[6]), float(f[7]), bytes(payload[_CONFIG.size:]))

    def problem(self) -> str | None:
        """Why this configuration cannot describe a rotating radar's beams, or None."""
        if not self.azimuth_samples:
            return "azimuth_samples 0"
        if not self.encoder_size or self.encoder_size < self.azimuth_samples:
            return f"encoder_size {self.encoder_size} (fewer counts than the {self.azimuth_samples} azimuths)"
        if not self.range_in_bins:
            return "range_in_bins 0"
        if not (self.bin_size and np.isfinite(self.range_gain) and self.range_gain > 0):
            return f"range per bin {self.bin_size} x 0.1 mm x gain {self.range_gain}"
        if not np.isfinite(self.range_offset_m) or abs(self.range_offset_m) > 1e4:
            return f"range_offset {self.range_offset_m} m"
        if not self.rotation_speed_mhz:
            return "rotation_speed 0 mHz"
        return None


@dataclass(frozen=True)
class FftData:
    """One azimuth of FFT data (type 30, 8-bit samples; type 31, ``high_precision``, 16-bit
    big-endian). ``azimuth`` is the encoder count; ``seconds`` / ``split_seconds`` the device
    time (ns in the second); ``samples`` the raw sample bytes."""

    sweep_counter: int
    azimuth: int
    seconds: int
    split_seconds: int
    samples: bytes
    high_precision: bool = False

    @property
    def type(self) -> int:
        return MessageType.HIGH_PRECISION_FFT_DATA if self.high_precision else MessageType.FFT_DATA

    @property
    def device_ns(self) -> int:
        return self.seconds * 1_000_000_000 + self.split_seconds

    def values(self) -> np.ndarray:
        """The samples as uint8 (8-bit) or uint16 (16-bit, from big-endian)."""
        if self.high_precision:
            return np.frombuffer(self.samples, dtype=">u2").astype(np.uint16)
        return np.frombuffer(self.samples, dtype=np.uint8)

    def encode(self) -> bytes:
        """The payload: 14 header bytes, then the samples."""
        return (_FFT.pack(FFT_HEADER_BYTES, self.sweep_counter & 0xFFFF, self.azimuth)
                + _TIME.pack(self.seconds, self.split_seconds) + self.samples)

    @classmethod
    def decode(cls, payload: bytes, high_precision: bool) -> FftData:
        if len(payload) < FFT_HEADER_BYTES:
            raise ProtocolError(f"FFT data message: {len(payload)} payload bytes, expected at least "
                                f"{FFT_HEADER_BYTES}")
        offset, sweep, azimuth = _FFT.unpack_from(payload)
        seconds, split = _TIME.unpack_from(payload, _FFT.size)
        if not FFT_HEADER_BYTES <= offset <= len(payload):
            raise ProtocolError(f"FFT data message: fft_data_offset {offset} outside the payload "
                                f"({FFT_HEADER_BYTES}..{len(payload)})")
        if split >= 1_000_000_000:
            raise ProtocolError(f"FFT data message (azimuth {azimuth}): split_seconds {split} is not below "
                                "1e9 ns")
        samples = bytes(payload[offset:])
        if high_precision and len(samples) % 2:
            raise ProtocolError(f"16-bit FFT data message (azimuth {azimuth}): an odd number of sample bytes "
                                f"({len(samples)})")
        return cls(sweep, azimuth, seconds, split, samples, high_precision)


class StreamDecoder:
    """Whole messages from a byte stream fed in arbitrary chunks (short reads).

    :meth:`feed` returns the messages completed so far and keeps at most one partial message
    (22 + ``max_payload_bytes`` bytes at most: a bigger size is refused at its header, before
    any payload is buffered). A framing error (:func:`decode_header`) leaves the decoder
    unusable (make a new one on a new connection): it is raised at once when no whole message
    came before it in the bytes fed, else those messages are returned first, the error kept in
    :attr:`error` and raised by the next :meth:`feed`."""

    def __init__(self, max_payload_bytes: int = MAX_PAYLOAD_BYTES) -> None:
        if max_payload_bytes < 1:
            raise ValueError("max_payload_bytes must be at least 1")
        self.max_payload_bytes = int(max_payload_bytes)
        self._buf = bytearray()
        self._need: tuple[int, int] | None = None  # (type, payload size) of the header read
        self.offset = 0  # stream position of the buffer's first byte
        self.messages = 0
        self._broken: str | None = None
        self.error: ProtocolError | None = None

    @property
    def buffered(self) -> int:
        """Bytes held (at most one partial message)."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Message]:
        if self._broken:
            raise ProtocolError(self._broken)
        self._buf += data
        out: list[Message] = []
        buf = self._buf
        pos = 0
        try:
            while True:
                if self._need is None:
                    if len(buf) - pos < HEADER_BYTES:
                        break
                    _, msg_type, size = decode_header(bytes(buf[pos:pos + HEADER_BYTES]), self.max_payload_bytes,
                                                      self.offset + pos)
                    self._need = (msg_type, size)
                    pos += HEADER_BYTES
                msg_type, size = self._need
                if len(buf) - pos < size:
                    break
                out.append(Message(msg_type, bytes(buf[pos:pos + size])))
                pos += size
                self._need = None
                self.messages += 1
        except ProtocolError as e:
            self._broken, self.error = str(e), e
            if not out:
                raise
        finally:
            del buf[:pos]
            self.offset += pos
        return out
