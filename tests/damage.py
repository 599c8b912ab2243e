"""Ways to damage an input file, shared by the tests and ``benchmarks/fuzz_inputs.py``.

Each helper reads ``src`` and writes the damaged copy to ``dst`` (``src`` itself when ``dst`` is
None), so a raw test file can be spoilt in place or copied. Offsets into the data section of a
C3D file come from its header (``c3d_data_offset``); text exports are damaged as bytes. Bags (ROS1,
MCAP, ROS2 sqlite3) are parsed here to aim damage at a record, a region or one field of a pose
message (``bag_regions``, ``set_pose_field``); edits of the message list (``edit_poses`` ...) make,
through the writers of ``synth localisation``, the damage that a byte flip rarely reaches.
"""

from __future__ import annotations

import random
import struct
from pathlib import Path

import numpy as np

C3D_BLOCK = 512


def _out(src: Path, dst: Path | None) -> Path:
    return Path(src) if dst is None else Path(dst)


def truncate(src, keep: int, dst=None) -> Path:
    """Keep the first ``keep`` bytes (negative: drop the last ``-keep`` bytes)."""
    data = Path(src).read_bytes()
    out = _out(src, dst)
    out.write_bytes(data[:keep])
    return out


def overwrite(src, offset: int, payload: bytes, dst=None) -> Path:
    """Replace ``len(payload)`` bytes at ``offset`` (negative: from the end)."""
    data = bytearray(Path(src).read_bytes())
    start = offset if offset >= 0 else len(data) + offset
    data[start:start + len(payload)] = payload
    out = _out(src, dst)
    out.write_bytes(bytes(data))
    return out


def replace_bytes(src, old: bytes, new: bytes, dst=None) -> Path:
    """Replace the first occurrence of ``old`` (which must occur) by ``new``."""
    data = Path(src).read_bytes()
    assert old in data, old
    out = _out(src, dst)
    out.write_bytes(data.replace(old, new, 1))
    return out


def mutate(src, seed: int, n: int = 1, start: int = 0, stop: int | None = None, dst=None) -> tuple[Path, list[int]]:
    """Set ``n`` random bytes in ``[start, stop)`` to random values (reproducible with ``seed``).

    Returns the damaged file and the offsets changed (a byte may be set to its own value).
    """
    data = bytearray(Path(src).read_bytes())
    rng = random.Random(seed)
    stop = len(data) if stop is None else min(stop, len(data))
    offsets = sorted(rng.randrange(start, stop) for _ in range(n)) if stop > start else []
    for i in offsets:
        data[i] = rng.randrange(256)
    out = _out(src, dst)
    out.write_bytes(bytes(data))
    return out, offsets


def _bytes(src) -> bytes:
    return src if isinstance(src, (bytes, bytearray)) else Path(src).read_bytes()


def c3d_data_offset(src) -> int:
    """Byte offset of the data section of a C3D file or its bytes (header word 9: its 512-byte block, from 1)."""
    data = _bytes(src)
    param = (data[0] - 1) * C3D_BLOCK
    order = ">" if len(data) > param + 3 and data[param + 3] == 86 else "<"  # processor type 86: MIPS (big-endian)
    block, = struct.unpack(order + "H", data[16:18])
    return (block - 1) * C3D_BLOCK


def c3d_layout(src) -> dict[str, int | bool]:
    """Header facts of a C3D file or its bytes (Intel or DEC byte order): points, analog words per frame, frames,
    float data."""
    data = _bytes(src)
    points, analogs, first, last = struct.unpack("<4H", data[2:10])
    proc = data[(data[0] - 1) * C3D_BLOCK + 3]
    is_float = bool(data[{84: 15, 85: 13, 86: 12}.get(proc, 15)] & 0x80)  # sign bit of the header's scale factor
    return {"points": points, "analogs": analogs, "frames": last - first + 1, "float": is_float}


def c3d_value_offset(src, frame: int, point: int, axis: int) -> int:
    """Byte offset of one coordinate (``axis`` 0..2) of ``point`` at ``frame`` in the data section of a
    C3D file (4-byte floats or 2-byte integers, points then analog words in each frame)."""
    lay = c3d_layout(src)
    size = 4 if lay["float"] else 2
    return c3d_data_offset(src) + (frame * (4 * lay["points"] + lay["analogs"]) + point * 4 + axis) * size


def c3d_set_float(src, frame: int, point: int, axis: int, value: float, dst=None) -> Path:
    """Write ``value`` (float32, Intel byte order) as one coordinate of a point in a float C3D."""
    return overwrite(src, c3d_value_offset(src, frame, point, axis), struct.pack("<f", value), dst)


def c3d_mutate_data(src, seed: int, n: int = 1, dst=None) -> tuple[Path, list[int]]:
    """``mutate`` restricted to the data section of a C3D file."""
    return mutate(src, seed, n, start=c3d_data_offset(src), dst=dst)


def scale_values(values: np.ndarray, factor: float, rows: slice | np.ndarray | None = None) -> np.ndarray:
    """A copy of ``values`` with ``rows`` (all by default) multiplied by ``factor``."""
    out = np.array(values, dtype=float, copy=True)
    out[slice(None) if rows is None else rows] *= factor
    return out


def c3d_parameter_records(src) -> list[dict]:
    """The records of a C3D parameter section: name, group id (negative for a group), offset of the
    record, and the offsets of its structural bytes (name length, group id, next-record pointer,
    type, dimensions, description length), for damage aimed at the structure rather than the values."""
    data = _bytes(src)
    start = (data[0] - 1) * C3D_BLOCK
    section = data[start:start + data[start + 2] * C3D_BLOCK]
    out, pos = [], 4
    while pos + 4 <= len(section):
        nchar, gid = struct.unpack("bb", section[pos:pos + 2])
        if nchar == 0:
            break
        name_end = pos + 2 + abs(nchar)
        offset, = struct.unpack("<h", section[name_end:name_end + 2])
        body = name_end + 2
        places = [pos, pos + 1, name_end, name_end + 1]
        if gid < 0:
            places.append(body)
        elif body + 2 <= len(section):
            dtype, ndims = struct.unpack("bB", section[body:body + 2])
            dims = section[body + 2:body + 2 + ndims]
            places += [body, body + 1, *range(body + 2, body + 2 + len(dims)), body + 2 + ndims + abs(dtype) * int(np.prod(list(dims)))]
        out.append({"name": section[pos + 2:name_end].decode("latin-1"), "gid": gid, "offset": start + pos,
                    "structure": [start + p for p in places if start + p < len(data)]})
        if offset <= 0:
            break
        pos = name_end + offset
    return out


# ---- bags: ROS1 (.bag v2.0), MCAP, ROS2 sqlite3 (.db3) ------------------------------------------
ROS1_MAGIC = b"#ROSBAG V2.0\n"
ROS1_OPS = {2: "message", 3: "bag-header", 4: "index", 5: "chunk", 6: "chunk-info", 7: "connection"}
MCAP_MAGIC = b"\x89MCAP0\r\n"
MCAP_OPS = {1: "header", 2: "footer", 3: "schema", 4: "channel", 5: "message", 6: "chunk", 7: "message-index",
            8: "chunk-index", 9: "attachment", 10: "attachment-index", 11: "statistics", 12: "metadata",
            13: "metadata-index", 14: "summary-offset", 15: "data-end"}
SQLITE_MAGIC = b"SQLite format 3\x00"
POSE_FIELDS = ("x", "y", "z", "qx", "qy", "qz", "qw")


def bag_kind(src) -> str | None:
    """'ros1', 'mcap' or 'sqlite' from the magic bytes of a bag file (or its bytes); None otherwise."""
    head = _bytes(src)[:16]
    return "ros1" if head.startswith(ROS1_MAGIC) else "mcap" if head.startswith(MCAP_MAGIC) else \
        "sqlite" if head.startswith(SQLITE_MAGIC) else None


def _u32(data: bytes, at: int) -> int:
    return struct.unpack_from("<I", data, at)[0]


def ros1_records(src) -> list[dict]:
    """The records of a ROS1 bag, those inside uncompressed chunks too, in file order: ``op`` (name),
    ``offset``, ``end``, ``fields`` (header field name -> (start, end) of its value), ``structure``
    (offsets of the length fields and field names), ``body`` (start, end) of the data part, and
    ``chunk`` (offset of the enclosing chunk record, or None)."""
    data = _bytes(src)
    out: list[dict] = []

    def walk(pos: int, end: int, chunk: int | None) -> None:
        while pos + 4 <= end:
            hend = pos + 4 + _u32(data, pos)
            if hend + 4 > end:
                return
            dend = hend + 4 + _u32(data, hend)
            if dend > end:
                return
            fields, structure, at = {}, [*range(pos, pos + 4), *range(hend, hend + 4)], pos + 4
            while at + 4 <= hend:
                flen = _u32(data, at)
                name, eq, _ = data[at + 4:min(at + 4 + flen, hend)].partition(b"=")
                if not eq:
                    break
                fields[name.decode("latin-1")] = (at + 5 + len(name), at + 4 + flen)
                structure += range(at, at + 5 + len(name))
                at += 4 + flen
            op = data[fields["op"][0]] if "op" in fields else -1
            out.append({"op": ROS1_OPS.get(op, f"op {op}"), "offset": pos, "end": dend, "fields": fields,
                        "structure": structure, "body": (hend + 4, dend), "chunk": chunk})
            if op == 5 and "compression" in fields and data[slice(*fields["compression"])] == b"none":
                walk(hend + 4, dend, pos)
            pos = dend

    walk(len(ROS1_MAGIC), len(data), None)
    return out


def mcap_records(src) -> list[dict]:
    """The records of an MCAP file, those inside uncompressed chunks too, in file order: ``op`` (name),
    ``offset``, ``end``, ``structure`` (offsets of the opcode, the length and the fixed fields of a
    chunk or message), ``body`` (start, end) of the content after those fields, and ``chunk``."""
    data = _bytes(src)
    out: list[dict] = []

    def walk(pos: int, end: int, chunk: int | None) -> None:
        while pos + 9 <= end:
            op = data[pos]
            content = pos + 9
            stop = content + struct.unpack_from("<Q", data, pos + 1)[0]
            if stop > end:
                return
            fixed = 0
            compression = None
            if op == 6 and content + 36 <= stop:  # start, end, uncompressed size, crc; compression; records length
                clen = _u32(data, content + 28)
                compression = data[content + 32:content + 32 + clen]
                fixed = 32 + clen + 8
            elif op == 5:  # channel id, sequence, log time, publish time
                fixed = 22
            body = min(content + fixed, stop)
            out.append({"op": MCAP_OPS.get(op, f"op {op}"), "offset": pos, "end": stop,
                        "structure": list(range(pos, body)), "body": (body, stop), "chunk": chunk})
            if op == 6 and compression == b"":
                walk(body, stop, pos)
            pos = stop

    walk(len(MCAP_MAGIC), len(data) - len(MCAP_MAGIC), None)
    return out


def _sqlite(data: bytes):
    import sqlite3

    con = sqlite3.connect(":memory:")
    con.deserialize(data)
    return con


def _runs(offsets) -> list[tuple[int, int]]:
    """Sorted offsets as (start, end) ranges of consecutive bytes."""
    out: list[list[int]] = []
    for o in sorted(set(offsets)):
        if out and out[-1][1] == o:
            out[-1][1] = o + 1
        else:
            out.append([o, o + 1])
    return [tuple(r) for r in out]


def bag_messages(src) -> list[dict]:
    """The messages of a ROS1 bag, an MCAP file (uncompressed chunks) or a ROS2 sqlite3 file, in file
    order: ``topic``, ``body`` (start, end) of the serialised message, ``encoding`` ('ros1' or 'cdr')."""
    data = _bytes(src)
    kind = bag_kind(data)
    out = []
    if kind == "ros1":
        records = ros1_records(data)
        topics = {data[slice(*r["fields"]["conn"])]: data[slice(*r["fields"]["topic"])].decode()
                  for r in records if r["op"] == "connection"}
        out = [{"topic": topics.get(data[slice(*r["fields"]["conn"])], "?"), "body": r["body"], "encoding": "ros1"}
               for r in records if r["op"] == "message" and "conn" in r["fields"]]
    elif kind == "mcap":
        records = mcap_records(data)
        channels = {}
        for r in records:
            if r["op"] == "channel":
                at = r["body"][0]
                cid = struct.unpack_from("<H", data, at)[0]
                tlen = _u32(data, at + 4)
                topic = data[at + 8:at + 8 + tlen].decode()
                at += 8 + tlen
                enc = data[at + 4:at + 4 + _u32(data, at)].decode()
                channels[cid] = (topic, enc)
        for r in records:
            if r["op"] == "message":
                topic, enc = channels.get(struct.unpack_from("<H", data, r["offset"] + 9)[0], ("?", "cdr"))
                out.append({"topic": topic, "body": r["body"], "encoding": "ros1" if enc == "ros1" else "cdr"})
    elif kind == "sqlite":
        con = _sqlite(data)
        rows = con.execute("SELECT topics.name, messages.data FROM messages JOIN topics ON messages.topic_id = topics.id "
                           "ORDER BY messages.id").fetchall()
        con.close()
        at = 0
        for topic, blob in rows:
            start = data.find(blob, at)
            if start < 0:  # out of file order (or spread over overflow pages): search from the start
                start = data.find(blob)
            if start >= 0:
                out.append({"topic": topic, "body": (start, start + len(blob)), "encoding": "cdr"})
                at = start + len(blob)
    return out


def bag_regions(src) -> dict[str, list[tuple[int, int]]]:
    """Byte ranges of a bag file by role, for damage aimed at one part of the container:

    - ``header``: the file header (ROS1 magic and bag-header record, MCAP magic and header record,
      the 100-byte SQLite header);
    - ``index``: what locates the messages (ROS1 index-data, connection and chunk-info records; the
      MCAP message indexes and summary section; SQLite b-tree interior pages and the schema page);
    - ``chunk``: the structure of the data part (record and chunk headers, lengths; SQLite leaf-page
      headers and cell pointers);
    - ``payload``: the serialised messages.
    """
    data = _bytes(src)
    kind = bag_kind(data)
    regions: dict[str, list] = {"header": [], "index": [], "chunk": [], "payload": []}
    if kind == "ros1":
        for r in ros1_records(data):
            if r["op"] == "bag-header":
                regions["header"] += [(0, r["end"])]
            elif r["op"] in ("index", "chunk-info") or (r["op"] == "connection" and r["chunk"] is None):
                regions["index"] += [(r["offset"], r["end"])]
            elif r["op"] == "message":
                regions["chunk"] += _runs(r["structure"])
                regions["payload"] += [r["body"]]
            elif r["op"] == "chunk" and r["chunk"] is None and data[slice(*r["fields"]["compression"])] != b"none":
                regions["chunk"] += _runs(r["structure"])
                regions["payload"] += [r["body"]]  # compressed messages
            else:
                regions["chunk"] += _runs(r["structure"]) if r["op"] == "chunk" else [(r["offset"], r["end"])]
    elif kind == "mcap":
        records = mcap_records(data)
        summary = next((r["offset"] for r in records if r["op"] == "data-end"), len(data))
        for r in records:
            if r["op"] == "header":
                regions["header"] += [(0, r["end"])]
            elif r["op"] == "message-index" or r["offset"] >= summary:
                regions["index"] += [(r["offset"], r["end"])]
            elif r["op"] == "message":
                regions["chunk"] += _runs(r["structure"])
                regions["payload"] += [r["body"]]
            elif r["op"] == "chunk" and r["chunk"] is None and not any(q["chunk"] == r["offset"] for q in records):
                regions["chunk"] += _runs(r["structure"])
                regions["payload"] += [r["body"]]  # compressed messages
            else:
                regions["chunk"] += _runs(r["structure"]) if r["op"] == "chunk" else [(r["offset"], r["end"])]
        regions["index"] += [(len(data) - len(MCAP_MAGIC), len(data))]
    elif kind == "sqlite":
        size = struct.unpack_from(">H", data, 16)[0]
        size = 65536 if size == 1 else size
        regions["header"] = [(0, 100)]
        regions["index"] = [(100, size)]
        for start in range(size, len(data), size):
            ptype = data[start]
            if ptype in (0x02, 0x05, 0x0A):
                regions["index"] += [(start, start + size)]
            elif ptype == 0x0D:
                cells = struct.unpack_from(">H", data, start + 3)[0]
                regions["chunk"] += [(start, start + 8 + 2 * cells)]
        regions["payload"] = [m["body"] for m in bag_messages(data)]
    else:
        raise ValueError("not a ROS1 bag, an MCAP file or an SQLite file")
    return {k: [(a, b) for a, b in v if b > a] for k, v in regions.items()}


def pose_offsets(data: bytes, message: dict) -> dict[str, int]:
    """Offsets of the stamp (``sec``, ``nanosec``: uint32) and the pose (``x`` .. ``qw``: float64) of
    a serialised ``geometry_msgs/PoseStamped`` (one item of ``bag_messages``), ROS1 or little-endian CDR."""
    start, end = message["body"]
    # ROS1: seq, stamp, frame_id; CDR: encapsulation header, stamp, frame_id (with its NUL), doubles 8-aligned
    stamp = start + 4
    frame_len = _u32(data, stamp + 8)
    pos = stamp + 12 + frame_len
    if message["encoding"] == "cdr":
        pos = start + 4 + -(-(pos - start - 4) // 8) * 8
    if pos + 56 > end:
        raise ValueError(f"not a PoseStamped message at {start}")
    return {"sec": stamp, "nanosec": stamp + 4, **{f: pos + 8 * k for k, f in enumerate(POSE_FIELDS)}}


def pose_of(src, topic: str, index: int, messages: list[dict] | None = None) -> dict:
    """Stamp (s) and pose of the ``index``-th message of the PoseStamped ``topic`` of a bag file, with
    the offsets of its fields (``pose_offsets``); ``messages``: its ``bag_messages``, if known."""
    data = _bytes(src)
    msgs = [m for m in (bag_messages(data) if messages is None else messages) if m["topic"] == topic]
    at = pose_offsets(data, msgs[index])
    sec, nsec = struct.unpack_from("<II", data, at["sec"])
    values = {f: struct.unpack_from("<d", data, at[f])[0] for f in POSE_FIELDS}
    return {"t": sec + nsec * 1e-9, "sec": sec, "nanosec": nsec, **values, "offsets": at}


def set_pose_field(src, topic: str, index: int, field: str, value, dst=None) -> tuple[Path, dict]:
    """Write ``value`` into one field (``sec``, ``nanosec``, ``x`` .. ``qw``) of the ``index``-th message
    of a PoseStamped ``topic`` of an uncompressed bag file; returns the file and the message's
    original stamp and pose (``pose_of``)."""
    before = pose_of(src, topic, index)
    payload = struct.pack("<I", int(value) & 0xFFFFFFFF) if field in ("sec", "nanosec") else struct.pack("<d", float(value))
    return overwrite(src, before["offsets"][field], payload, dst), before


def db3_set(src, topic: str, index: int, column: str, value, dst=None) -> Path:
    """Store ``value`` in ``column`` (``timestamp`` or ``data``) of the ``index``-th message of ``topic`` of
    a ROS2 sqlite3 file, as a flipped type byte of a record header does (e.g. a timestamp read as a blob)."""
    import shutil
    import sqlite3

    out = _out(src, dst)
    if out != Path(src):
        shutil.copy(src, out)
    con = sqlite3.connect(out)
    with con:
        con.execute(f"UPDATE messages SET {column} = ? WHERE id = (SELECT messages.id FROM messages JOIN topics "
                    "ON messages.topic_id = topics.id WHERE topics.name = ? ORDER BY messages.id LIMIT 1 OFFSET ?)",
                    (value, topic, index))
    con.close()
    return out


# ---- bags: edits of the message list before writing (``synth.write_*(..., edit=...)``) -----------
# An edit maps the list of ``(record ns, topic, msgtype, message)`` of a synthetic run, and the
# typestore it was made with, to the list the writer writes: structure damage that a byte flip
# rarely reaches (a topic missing or renamed, poses NaN or with a zero quaternion, stamps out of order).
POSE_TOPICS = ("/mocap/pose", "/icp/pose", "/goal")  # the PoseStamped topics of `synth localisation`


def edit_poses(fn, topics=POSE_TOPICS):
    """Replace the pose of each PoseStamped message on ``topics`` by ``fn(topic, i, xyz, quat) -> (xyz, quat)``
    (``i``: the message's index on its topic)."""
    def edit(msgs, store):
        T = store.types
        out, count = [], {}
        for ts, topic, msgtype, m in msgs:
            if topic in topics:
                i = count[topic] = count.get(topic, -1) + 1
                p, q = m.pose.position, m.pose.orientation
                xyz, quat = fn(topic, i, np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]))
                m = T[msgtype](header=m.header, pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                    orientation=T["geometry_msgs/msg/Quaternion"](x=float(quat[0]), y=float(quat[1]), z=float(quat[2]),
                                                                  w=float(quat[3]))))
            out.append((ts, topic, msgtype, m))
        return out
    return edit


def edit_stamp(topic: str, index: int, sec: int | None = None, nanosec: int | None = None):
    """Set the header stamp (``sec``, ``nanosec``) of the ``index``-th message on ``topic``."""
    from dataclasses import replace

    def edit(msgs, store):
        out, i = [], -1
        for ts, tp, mt, m in msgs:
            if tp == topic:
                i += 1
                if i == index:
                    st = m.header.stamp
                    stamp = replace(st, sec=st.sec if sec is None else sec, nanosec=st.nanosec if nanosec is None else nanosec)
                    m = replace(m, header=replace(m.header, stamp=stamp))
            out.append((ts, tp, mt, m))
        return out
    return edit


def rename_topic(old: str, new: str):
    """Messages of topic ``old`` recorded as ``new``."""
    return lambda msgs, store: [(t, new if tp == old else tp, mt, m) for t, tp, mt, m in msgs]


def drop_topic(topic: str):
    """The topic left out of the recording."""
    return lambda msgs, store: [x for x in msgs if x[1] != topic]


def swap_messages(topic: str, pairs):
    """Swap the messages ``(a, b)`` of each pair (indices on ``topic``), keeping the record times: their
    stamps are then out of order."""
    def edit(msgs, store):
        idx = [i for i, x in enumerate(msgs) if x[1] == topic]
        msgs = list(msgs)
        for a, b in pairs:
            ia, ib = idx[a], idx[b]
            msgs[ia], msgs[ib] = (msgs[ia][0], *msgs[ib][1:]), (msgs[ib][0], *msgs[ia][1:])
        return msgs
    return edit


def add_static_tf(parent: str, child: str, stamp: float):
    """A /tf_static transform ``parent -> child`` (identity) recorded first (e.g. a frame island)."""
    def edit(msgs, store):
        T = store.types
        header = dict(stamp=T["builtin_interfaces/msg/Time"](sec=int(stamp), nanosec=0), frame_id=parent)
        if "seq" in T["std_msgs/msg/Header"].__dataclass_fields__:
            header["seq"] = 0
        tr = T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](**header), child_frame_id=child, transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
        return [(int(stamp * 1e9), "/tf_static", "tf2_msgs/msg/TFMessage", T["tf2_msgs/msg/TFMessage"](transforms=[tr]))] + list(msgs)
    return edit


def c3d_parameter_offset(src, group: str, name: str) -> int:
    """Byte offset of the first value of parameter ``group:name`` in a C3D file (for damage aimed at one value)."""
    data = _bytes(src)
    records = c3d_parameter_records(data)
    gid = next(-r["gid"] for r in records if r["gid"] < 0 and r["name"].strip().upper() == group.upper())
    rec = next(r for r in records if r["gid"] == gid and r["name"].strip().upper() == name.upper())
    body = rec["structure"][3] + 1  # after the next-record pointer
    return body + 2 + data[body + 1]  # type, number of dimensions, dimensions


def c3d_set_parameter(src, group: str, name: str, payload: bytes, dst=None) -> Path:
    """Overwrite the first value(s) of parameter ``group:name`` with ``payload`` (e.g. ``struct.pack('<f', 0.0)``)."""
    return overwrite(src, c3d_parameter_offset(src, group, name), payload, dst)
