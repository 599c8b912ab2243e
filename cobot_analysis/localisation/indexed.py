"""Pose topics read straight through a bag's own index, vectorised: ROS1 ``.bag`` (v2.0) and MCAP.

Both containers index every message: ROS1 per chunk and connection ``(time, offset)`` in the
decompressed chunk, MCAP per chunk and channel ``(log_time, offset)`` in the decompressed chunk
records. A topic's messages are then gathered with numpy at those offsets instead of being iterated
one by one. Only what is exactly as expected is read here: one message record layout and one
message size per topic, known compressions, the CRCs MCAP gives matching; anything else returns
None and the general reader (``bags.open_bag``, rosbags and mcap) reads the bag and reports on it.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
_U32 = struct.Struct("<I").unpack_from
_U64 = struct.Struct("<Q").unpack_from
_U16 = struct.Struct("<H").unpack_from


class Unexpected(Exception):
    """The bag is not laid out as this reader expects: let the general reader have it."""


@dataclass
class Messages:
    """One topic's messages: record (log) times in ns, and the serialised messages, one per row."""

    record_ns: np.ndarray
    data: np.ndarray  # (n, size) uint8


@dataclass
class IndexedBag:
    path: Path
    container: str  # "ros1" (.bag) or "mcap"
    ros1: bool  # message encoding: ROS1 serialisation (else CDR)
    topics: dict[str, str] = field(default_factory=dict)  # topic -> msgtype (pkg/msg/Name)
    _file: "_File | None" = None
    _conns: dict[str, list[int]] = field(default_factory=dict)  # topic -> connection / channel ids
    _chunks: list = field(default_factory=list)  # per chunk: (data reader, {id: (times_ns, offsets)})

    def read(self, topics: list[str]) -> dict[str, Messages] | None:
        """The messages of each topic in record order (file order for ROS1, log-time order for MCAP),
        or None when a topic has none or its messages do not share one size and record layout. One
        pass over the chunks: each chunk holding a wanted message is read and decompressed once."""
        try:
            return self._read(topics)
        except Exception:  # noqa: BLE001 - anything unexpected: the general reader reads and reports
            return None

    def _read(self, topics: list[str]) -> dict[str, Messages] | None:
        ids = {topic: self._conns[topic] for topic in topics}
        chunks = [(chunk, {topic: [index[i] for i in ids[topic] if i in index] for topic in topics})
                  for chunk, index in self._chunks]
        chunks = [(chunk, {topic: e for topic, e in wanted.items() if e}) for chunk, wanted in chunks]
        chunks = [(chunk, wanted) for chunk, wanted in chunks if wanted]
        total = {topic: sum(len(e[0]) for _, wanted in chunks for e in wanted.get(topic, ())) for topic in topics}
        if min(total.values(), default=0) == 0:
            return None
        t = {topic: np.empty(n, np.int64) for topic, n in total.items()}
        data: dict[str, np.ndarray] = {}
        k = dict.fromkeys(topics, 0)
        for chunk, wanted in chunks:
            arr = np.frombuffer(chunk(), dtype=np.uint8)
            for topic, entries in wanted.items():
                ct = np.concatenate([e[0] for e in entries])
                off = np.concatenate([e[1] for e in entries])
                order = np.argsort(off, kind="stable")
                ct, off = ct[order], off[order]
                start, size = self._starts(arr, off, ids[topic])
                out = data.get(topic)
                if out is None:
                    out = data[topic] = np.empty((total[topic], size), np.uint8)
                if size != out.shape[1] or int(start.max()) + size > len(arr):
                    return None
                if self.container == "mcap" and np.any(_u64s(arr, off + 15).astype(np.int64) != ct):
                    return None  # the general reader takes the log time from the message record itself
                j = k[topic]
                t[topic][j:j + len(ct)] = ct
                out[j:j + len(ct)] = _gather(arr, start, size)
                k[topic] = j + len(ct)
        msgs = {}
        for topic in topics:
            tt, dd = t[topic], data[topic]
            if self.container == "mcap":  # the general reader merges MCAP chunks by log time
                order = np.argsort(tt, kind="stable")
                tt, dd = tt[order], dd[order]
            msgs[topic] = Messages(tt, dd)
        return msgs

    def _starts(self, arr: np.ndarray, off: np.ndarray, ids: list[int]) -> tuple[np.ndarray, int]:
        """Start of each message's data and the one data size (``Unexpected`` if they differ)."""
        if len(off) == 0 or int(off.max()) + 16 > len(arr):
            raise Unexpected
        if self.container == "ros1":
            hl = _u32s(arr, off)
            if np.any(hl != hl[0]):
                raise Unexpected
            hl0 = int(hl[0])
            header = bytes(arr[int(off[0]) + 4:int(off[0]) + 4 + hl0])
            first = _fields(header)  # also checks its syntax
            if first.get("op") != b"\x02" or "conn" not in first:
                raise Unexpected
            for name in ("op", "conn"):  # every message record's op and connection as the first's
                a, b = _field_span(header, name)
                if not np.all(_gather(arr, off + 4 + a, b - a) == np.frombuffer(header[a:b], np.uint8)):
                    raise Unexpected
            if _U32(first["conn"])[0] not in ids:
                raise Unexpected
            dl = _u32s(arr, off + 4 + hl0)
            if np.any(dl != dl[0]):
                raise Unexpected
            return off + 8 + hl0, int(dl[0])
        # MCAP message record: opcode 0x05, u64 length, u16 channel, u32 sequence, u64 log and publish times
        op = arr[off]
        length = _u64s(arr, off + 1)
        channel = arr[off + 9].astype(np.int64) | (arr[off + 10].astype(np.int64) << 8)
        if np.any(op != 0x05) or np.any(length != length[0]) or not np.isin(channel, ids).all() or int(length[0]) < 22:
            raise Unexpected
        return off + 31, int(length[0]) - 22


def _u32s(arr: np.ndarray, at: np.ndarray) -> np.ndarray:
    b = _gather(arr, at, 4).astype(np.uint32)
    return b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16) | (b[:, 3] << 24)


def _u64s(arr: np.ndarray, at: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(_gather(arr, at, 8)).view("<u8")[:, 0]


def _gather(arr: np.ndarray, start: np.ndarray, width: int) -> np.ndarray:
    """Rows ``arr[start[i]:start[i] + width]`` as an ``(n, width)`` array (rows of a sliding-window view:
    one copy per row instead of one index per byte; ``IndexError`` past the end, as plain indexing)."""
    if width == 0:
        return np.empty((len(start), 0), np.uint8)
    return sliding_window_view(arr, width)[start]


def _fields(header: bytes) -> dict[str, bytes]:
    """ROS1 record header: ``u32 length, name=value`` fields."""
    out, pos = {}, 0
    while pos < len(header):
        (n,) = _U32(header, pos)
        pos += 4
        if n > len(header) - pos:
            raise Unexpected
        name, sep, value = header[pos:pos + n].partition(b"=")
        if not sep:
            raise Unexpected
        out[name.decode("ascii")] = value
        pos += n
    return out


def _field_span(header: bytes, name: str) -> tuple[int, int]:
    """Byte range of the value of field ``name`` in a ROS1 record header ((0, 0) if absent)."""
    pos, key = 0, name.encode() + b"="
    while pos < len(header):
        (n,) = _U32(header, pos)
        if header[pos + 4:pos + 4 + len(key)] == key:
            return pos + 4 + len(key), pos + 4 + n
        pos += 4 + n
    return 0, 0


class _File:
    """Positioned reads of a file (only the parts asked for are read: the index, the chunks needed)."""

    def __init__(self, path: Path):
        with open(path, "rb") as fh:
            self.fd = os.dup(fh.fileno())
        self.size = os.fstat(self.fd).st_size

    def __del__(self):
        if hasattr(self, "fd"):
            os.close(self.fd)

    def __len__(self) -> int:
        return self.size

    def read(self, pos: int, n: int) -> bytes:
        if pos < 0 or n < 0 or pos + n > self.size:
            raise Unexpected
        out = os.pread(self.fd, n, pos)
        if len(out) != n:
            raise Unexpected
        return out

    def __getitem__(self, pos: int) -> int:
        return self.read(pos, 1)[0]


def open_indexed(path: Path) -> IndexedBag | None:
    """The bag at ``path`` with its index read, or None (not ROS1/MCAP, or not as expected)."""
    path = Path(path)
    if not path.is_file() or path.suffix not in (".bag", ".mcap"):
        return None
    try:
        f = _File(path)
        magic = f.read(0, min(len(f), 13))
        if magic == ROS1_MAGIC:
            return _ros1(path, f)
        if magic[:len(MCAP_MAGIC)] == MCAP_MAGIC:
            return _mcap(path, f)
    except Exception:  # noqa: BLE001 - anything unexpected: the general reader reads and reports
        pass
    return None


def _ros2_name(name: str) -> str:
    parts = name.split("/")
    return name if len(parts) == 3 or len(parts) < 2 else f"{parts[0]}/msg/{parts[1]}"


# ---- ROS1 -------------------------------------------------------------------------------------
def _record(f: _File, pos: int, data: bool = False) -> tuple[dict[str, bytes], int, int, bytes | None]:
    """ROS1 record at ``pos``: header fields, data start and end, the data if asked for."""
    (hl,) = _U32(f.read(pos, 4))
    head = f.read(pos + 4, hl + 4)
    (dl,) = _U32(head, hl)
    start = pos + 8 + hl
    if start + dl > len(f):
        raise Unexpected
    return _fields(head[:hl]), start, start + dl, f.read(start, dl) if data else None


def _op(header: dict[str, bytes], op: int) -> None:
    if header.get("op") != bytes([op]):
        raise Unexpected


_INDEX = np.dtype([("sec", "<u4"), ("nsec", "<u4"), ("offset", "<u4")])


def _ros1(path: Path, buf: _File) -> IndexedBag:
    header, _, _, _ = _record(buf, len(ROS1_MAGIC))
    _op(header, 0x03)
    (index_pos,) = _U64(header["index_pos"])
    (n_conns,) = _U32(header["conn_count"])
    (n_chunks,) = _U32(header["chunk_count"])
    if index_pos < len(ROS1_MAGIC) or index_pos >= len(buf):
        raise Unexpected
    bag = IndexedBag(path, "ros1", ros1=True, _file=buf)
    pos = index_pos
    for _ in range(n_conns):
        header, _, pos, data = _record(buf, pos, data=True)
        _op(header, 0x07)
        conn = _U32(header["conn"])[0]
        topic = header["topic"].decode()
        msgtype = _ros2_name(_fields(data)["type"].decode())
        if bag.topics.setdefault(topic, msgtype) != msgtype:
            raise Unexpected
        bag._conns.setdefault(topic, []).append(conn)
    chunk_pos = []
    for _ in range(n_chunks):
        header, _, pos, _ = _record(buf, pos)
        _op(header, 0x06)
        if _U32(header["ver"])[0] != 1:
            raise Unexpected
        chunk_pos.append((_U64(header["chunk_pos"])[0], _U32(header["count"])[0]))
    for cpos, n_index in sorted(chunk_pos):
        header, start, end, _ = _record(buf, cpos)
        _op(header, 0x05)
        size = _U32(header["size"])[0]
        index, pos = {}, end
        for _ in range(n_index):
            ih, istart, pos, data = _record(buf, pos, data=True)
            _op(ih, 0x04)
            count = _U32(ih["count"])[0]
            if _U32(ih["ver"])[0] != 1 or pos - istart != 12 * count:
                raise Unexpected
            e = np.frombuffer(data, dtype=_INDEX, count=count)
            t = e["sec"].astype(np.int64) * 1_000_000_000 + e["nsec"]
            index[_U32(ih["conn"])[0]] = (t, e["offset"].astype(np.int64))
        bag._chunks.append((_ros1_chunk(buf, header["compression"].decode(), start, end, size), index))
    return bag


def _ros1_chunk(buf: _File, compression: str, start: int, end: int, size: int):
    def data():
        raw = buf.read(start, end - start)
        if compression == "none":
            out = raw
        elif compression == "bz2":
            import bz2

            out = bz2.decompress(raw)
        elif compression == "lz4":
            import lz4.frame

            out = lz4.frame.decompress(raw)
        else:
            raise Unexpected
        if len(out) != size:
            raise Unexpected
        return out

    return data


# ---- MCAP -------------------------------------------------------------------------------------
_MINDEX = np.dtype([("t", "<u8"), ("offset", "<u8")])


@dataclass
class _ChunkIndex:
    chunk_start_offset: int
    uncompressed_size: int
    message_index_offsets: dict[int, int]


def _mcap_summary(buf: _File) -> tuple[dict, dict, list[_ChunkIndex]]:
    """Schemas ``{id: name}``, channels ``{id: (topic, schema id, encoding)}`` and chunk indexes of
    the MCAP summary section (located by the footer; its CRC checked when the file gives one)."""
    end = len(buf) - len(MCAP_MAGIC)
    footer = buf.read(end - 29, 29)  # opcode 0x02, u64 length 20, summary start, summary offset start, CRC
    if footer[0] != 0x02 or _U64(footer, 1)[0] != 20 or buf.read(end, len(MCAP_MAGIC)) != MCAP_MAGIC:
        raise Unexpected
    start, offsets, crc = _U64(footer, 9)[0], _U64(footer, 17)[0], _U32(footer, 25)[0]
    stop = offsets or end - 29
    if start == 0 or not start < stop <= end - 29:
        raise Unexpected
    data = buf.read(start, stop - start)
    if crc and zlib.crc32(footer[:25], zlib.crc32(data + buf.read(stop, end - 29 - stop))) != crc:
        raise Unexpected
    schemas, channels, chunks, pos = {}, {}, [], 0

    def string(k: int) -> tuple[str, int]:
        (n,) = _U32(data, k)
        return data[k + 4:k + 4 + n].decode(), k + 4 + n

    while pos < len(data):
        op, (length,) = data[pos], _U64(data, pos + 1)
        k, pos = pos + 9, pos + 9 + length
        if pos > len(data):
            raise Unexpected
        if op == 0x03:  # Schema: u16 id, name, encoding, data
            schemas[_U16(data, k)[0]] = string(k + 2)[0]
        elif op == 0x04:  # Channel: u16 id, u16 schema id, topic, message encoding, metadata
            topic, j = string(k + 4)
            channels[_U16(data, k)[0]] = (topic, _U16(data, k + 2)[0], string(j)[0])
        elif op == 0x08:  # ChunkIndex: 4 x u64, map<u16, u64>, u64, compression, 2 x u64
            (n,) = _U32(data, k + 32)
            offsets = {_U16(data, j)[0]: _U64(data, j + 2)[0] for j in range(k + 36, k + 36 + n, 10)}
            j = string(k + 44 + n)[1]
            chunks.append(_ChunkIndex(_U64(data, k + 16)[0], _U64(data, j + 8)[0], offsets))
    return schemas, channels, chunks


def _mcap_header(buf: _File) -> None:
    """The Header record after the magic: opcode 0x01, u64 length, profile and library strings."""
    head = buf.read(len(MCAP_MAGIC), 9)
    (length,) = _U64(head, 1)
    data = buf.read(len(MCAP_MAGIC) + 9, length)
    (n,) = _U32(data, 0)
    (m,) = _U32(data, 4 + n)
    if head[0] != 0x01 or 8 + n + m != length:
        raise Unexpected
    data[4:4 + n].decode(), data[8 + n:8 + n + m].decode()


def _mcap(path: Path, buf: _File) -> IndexedBag:
    _mcap_header(buf)
    schemas, channels, chunks = _mcap_summary(buf)
    if not chunks or not channels:
        raise Unexpected
    encodings = {ch[2] for ch in channels.values()}
    if len(encodings) != 1 or not encodings <= {"cdr", "ros1"}:
        raise Unexpected
    bag = IndexedBag(path, "mcap", ros1=encodings == {"ros1"}, _file=buf)
    for cid, (topic, schema, _) in channels.items():
        msgtype = _ros2_name(schemas[schema])
        if bag.topics.setdefault(topic, msgtype) != msgtype:
            raise Unexpected
        bag._conns.setdefault(topic, []).append(cid)
    for ci in sorted(chunks, key=lambda c: c.chunk_start_offset):
        index = {}
        for cid, at in ci.message_index_offsets.items():
            head = buf.read(at, 15)  # opcode 0x07, u64 length, u16 channel, u32 byte length of the entries
            (length,) = _U64(head, 1)
            (n,) = _U32(head, 11)
            if head[0] != 0x07 or n % 16 or 6 + n > length or _U16(head, 9)[0] != cid:
                raise Unexpected
            e = np.frombuffer(buf.read(at + 15, n), dtype=_MINDEX)
            index[cid] = (e["t"].astype(np.int64), e["offset"].astype(np.int64))
        bag._chunks.append((_mcap_chunk(buf, ci), index))
    return bag


def _mcap_chunk(buf, ci):
    def data():
        at = ci.chunk_start_offset
        # opcode 0x06, u64 length, u64 start and end times, u64 uncompressed size, u32 CRC, compression, records
        head = buf.read(at, 41)
        (usize,) = _U64(head, 25)
        (crc,) = _U32(head, 33)
        (clen,) = _U32(head, 37)
        tail = buf.read(at + 41, clen + 8)
        compression = tail[:clen].decode()
        (rlen,) = _U64(tail, clen)
        if head[0] != 0x06 or usize != ci.uncompressed_size:
            raise Unexpected
        raw = buf.read(at + 49 + clen, rlen)
        if compression == "":
            out = raw
        elif compression == "zstd":
            import zstandard

            out = zstandard.ZstdDecompressor().decompress(raw, max_output_size=usize)
        elif compression == "lz4":
            import lz4.frame

            out = lz4.frame.decompress(raw)
        else:
            raise Unexpected
        if len(out) != usize or (crc and zlib.crc32(out) != crc):
            raise Unexpected
        return out

    return data
