"""Pose streams from ROS bags: ROS1 ``.bag``, ROS2 bag directories (sqlite3 or MCAP storage),
standalone ``.mcap`` / ``.db3`` files.

Containers are read with rosbags (``AnyReader``); MCAP files whose channels carry ROS1-encoded
messages (as written by ``mcap-ros1-support``), which rosbags reads as CDR, go through the mcap
library and are decoded with the rosbags ROS1 deserialiser. Messages give poses as:

- ``geometry_msgs/PoseStamped``: ``pose.position`` / ``pose.orientation``; ``nav_msgs/Odometry``
  and ``geometry_msgs/PoseWithCovarianceStamped``: ``pose.pose.position`` / ``pose.pose.orientation``;
- ``geometry_msgs/TransformStamped``: ``transform.translation`` / ``transform.rotation``;
- ``tf2_msgs/TFMessage`` on ``/tf`` and ``/tf_static``: the pose of ``child`` in ``parent``
  (spec ``tf:PARENT->CHILD``), chained over intermediate frames when it is not a single edge:
  ``T_parent_child(t) = T_1(t) T_2(t) ... T_k(t)`` along the path of the frame tree, static edges
  constant, dynamic edges interpolated (linear / slerp) at the stamps of the sparsest dynamic edge.

Stamps are header stamps (``sec + nanosec 1e-9``) unless ``time="record"`` (the bag's receive
time). Streams are sorted by time (with a warning when they were not) and exact duplicates of a
stamp are dropped.

A run is one bag, or the pieces of a split recording (``rosbag record --split``: ``run_0.bag``,
``run_1.bag``, ...) read as one (``runs_of``; rosbags' ``AnyReader`` merges several ROS1 bags). A ROS2
bag directory split into several files is one bag already.
"""

from __future__ import annotations

import os
import re
from collections import defaultdict, deque
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cobot_analysis.console import warn
from cobot_analysis.errors import InputError
from cobot_analysis.localisation.poses import PoseStream, compose, invert, normalise, row_norm, slerp

POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry", "geometry_msgs/msg/TransformStamped",
              "geometry_msgs/msg/PoseWithCovarianceStamped")
TF_TYPE = "tf2_msgs/msg/TFMessage"
TF_TOPICS = ("/tf", "/tf_static")
SUPPORTED = POSE_TYPES + (TF_TYPE,)
TF_MSGDEF = "geometry_msgs/TransformStamped[] transforms\n"


@dataclass(frozen=True)
class PoseSpec:
    """Where a pose stream is in a bag: a topic, or a tf frame pair ``tf:PARENT->CHILD`` (on ``/tf`` and
    ``/tf_static``), ``TOPIC:PARENT->CHILD`` on another tf topic (e.g. ``/robot1/tf``, with ``/robot1/tf_static``
    and ``/tf_static``; ROS topic names hold no ``:``)."""

    topic: str | None = None
    parent: str | None = None
    child: str | None = None
    tf_topic: str = "/tf"

    @classmethod
    def parse(cls, text: str) -> "PoseSpec":
        text = text.strip()
        tf_topic, colon, pair = text.partition(":")
        if colon and (tf_topic == "tf" or tf_topic.startswith("/")):
            parent, sep, child = pair.partition("->")
            if not sep or not parent.strip() or not child.strip():
                raise InputError(f"bad tf pose spec {text!r}", remedy="write it tf:PARENT->CHILD, e.g. tf:map->base_link "
                                                                       "(TOPIC:PARENT->CHILD on another tf topic)")
            return cls(parent=_frame(parent), child=_frame(child), tf_topic="/tf" if tf_topic == "tf" else tf_topic)
        if not text:
            raise InputError("empty pose topic", remedy="pass a topic such as /icp/pose or tf:map->base_link")
        return cls(topic=text)

    @property
    def is_tf(self) -> bool:
        return self.topic is None

    @property
    def tf_topics(self) -> tuple[str, ...]:
        """The tf topics a frame pair is read from: its dynamic topic and the static ones."""
        return (self.tf_topic, "/tf_static") if self.tf_topic == "/tf" else (self.tf_topic, f"{self.tf_topic}_static", "/tf_static")

    def __str__(self) -> str:
        if not self.is_tf:
            return str(self.topic)
        return f"{'tf' if self.tf_topic == '/tf' else self.tf_topic}:{self.parent}->{self.child}"


def _frame(name: str) -> str:
    return name.strip().lstrip("/")


# ---- containers -------------------------------------------------------------------------------
@dataclass
class Topic:
    name: str
    msgtype: str
    count: int


class _Source:
    """A bag opened for reading: its topics, ``raw(topics)`` yielding ``(topic, msgtype,
    record_ns, bytes)`` in record order, ``deserialize(bytes, msgtype)``, and ``span``: the record
    times of its first and last messages (ns)."""

    ros1 = False

    def __init__(self, path: Path):
        self.path = path
        self.topics: dict[str, Topic] = {}

    def messages(self, topics) -> Iterator[tuple[str, str, int, object]]:
        for topic, msgtype, ts, raw in self.raw(topics):
            yield topic, msgtype, ts, self.deserialize(raw, msgtype)

    def piece_at_fault(self, topics, decode: str | None = None) -> Path:
        """The file to name for a failure reading ``topics`` (or decoding their ``decode`` messages): the bag's."""
        return self.path


class _RosbagsSource(_Source):
    def __init__(self, path: Path, reader):
        super().__init__(path)
        self.reader = reader
        self.ros1 = not reader.is2
        for c in reader.connections:
            if not isinstance(c.topic, str) or not isinstance(c.msgtype, str):  # a damaged metadata.yaml
                raise ValueError(f"the topic {c.topic!r} has the message type {c.msgtype!r}, not a name")
            t = self.topics.setdefault(c.topic, Topic(c.topic, c.msgtype, 0))
            t.count += c.msgcount

    @property
    def span(self) -> tuple[int, int]:
        return self.reader.start_time, self.reader.end_time

    def piece_at_fault(self, topics, decode: str | None = None) -> Path:
        """Of the pieces of a joined run, the first whose own messages of ``topics`` fail to read (or, ``decode``:
        to decode as that type) when read alone; the run's name if none does (or for one bag)."""
        if len(self.reader.readers) < 2:
            return self.path
        for reader in self.reader.readers:
            conns = [c for c in self.reader.connections if c.topic in topics and c.owner is reader]
            try:
                for c, _, raw in reader.messages(connections=conns):
                    if c.msgtype == decode:
                        self.reader.deserialize(raw, c.msgtype)
            except Exception:  # noqa: BLE001 - whatever the readers raise on damage: this piece is the one
                return Path(reader.path)
        return self.path

    def raw(self, topics):
        conns = [c for c in self.reader.connections if c.topic in topics]
        if self.ros1 and len(self.reader.readers) == 1:
            fast = _ros1_chunk_scan(self.reader.readers[0], conns)
            if fast is not None:
                yield from fast
                return
        # One container: iterate it directly (AnyReader's merge of several bags is not needed).
        it = self.reader.readers[0].messages(connections=conns) if len(self.reader.readers) == 1 else self.reader.messages(connections=conns)
        for c, ts, raw in it:
            yield c.topic, c.msgtype, ts, raw

    def deserialize(self, raw, msgtype):
        return self.reader.deserialize(raw, msgtype)


def _ros1_chunk_scan(reader, conns) -> list | None:
    """Messages of ``conns`` from a ROS1 bag read chunk by chunk in file order (each chunk
    decompressed once; records sliced at the offsets of the bag's own index, which rosbags has
    parsed), or None when the bag does not look as expected (then rosbags reads it). Per topic
    the order is the recording order; no merge across topics is needed here."""
    import struct

    try:
        entries = sorted((e.chunk_pos, e.offset, e.time, c) for c in conns for e in reader.indexes[c.id])
        out = []
        u32 = struct.Struct("<I").unpack_from
        pos, buf = None, b""
        for chunk_pos, off, ts, c in entries:
            if chunk_pos != pos:
                chunk = reader.chunks[chunk_pos]
                reader.bio.seek(chunk.datapos)
                buf = chunk.decompressor(reader.bio.read(chunk.datasize))
                pos = chunk_pos
            (hl,) = u32(buf, off)
            if buf.find(b"op=\x02", off + 4, off + 4 + hl) < 0:
                return None
            (dl,) = u32(buf, off + 4 + hl)
            start = off + 8 + hl
            out.append((c.topic, c.msgtype, ts, buf[start:start + dl]))
        return out
    except (AttributeError, KeyError, TypeError, struct.error):
        return None


class _McapRos1Source(_Source):
    """MCAP with ROS1-encoded channels: containers by the mcap library, decoding by rosbags."""

    ros1 = True

    def __init__(self, path: Path, fh, reader, summary):
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        super().__init__(path)
        self.reader = reader
        stats = summary.statistics  # without statistics, a span that continues nothing (as rosbags' of an empty bag)
        self.span = (stats.message_start_time, stats.message_end_time) if stats else (2**63 - 1, 0)
        self.store = get_typestore(Stores.ROS1_NOETIC)
        self.channels = {}
        counts = summary.statistics.channel_message_counts if summary.statistics else {}
        for cid, ch in summary.channels.items():
            schema = summary.schemas[ch.schema_id]
            msgtype = _ros2_name(schema.name)
            if msgtype not in self.store.types:
                self.store.register(get_types_from_msg(schema.data.decode(), msgtype))
            self.channels[cid] = (ch.topic, msgtype)
            t = self.topics.setdefault(ch.topic, Topic(ch.topic, msgtype, 0))
            t.count += counts.get(cid, 0)

    def raw(self, topics):
        for _schema, channel, message in self.reader.iter_messages(topics=list(topics), log_time_order=True):
            topic, msgtype = self.channels[channel.id]
            yield topic, msgtype, message.log_time, message.data

    def deserialize(self, raw, msgtype):
        return self.store.deserialize_ros1(raw, msgtype)


def _ros2_name(name: str) -> str:
    """``geometry_msgs/PoseStamped`` -> ``geometry_msgs/msg/PoseStamped``."""
    parts = name.split("/")
    return name if len(parts) == 3 or len(parts) < 2 else f"{parts[0]}/msg/{parts[1]}"


def _mcap_ros1_summary(path: Path, fh):
    """The mcap summary if every channel of the file is ROS1-encoded, else None."""
    from mcap.reader import make_reader

    reader = make_reader(fh, validate_crcs=True)
    summary = reader.get_summary()
    if summary is None or not summary.channels:
        return None, None
    if all(ch.message_encoding == "ros1" for ch in summary.channels.values()):
        return reader, summary
    return None, None


_NOT_A_BAG = "give a ROS1 .bag file, a ROS2 bag directory (with metadata.yaml), or an .mcap/.db3 file"


def run_files(path) -> tuple[list[Path], Path]:
    """The files of a run (a bag, or the pieces of a split recording in order) and the name its messages
    give it: the bag's path, or ``DIR/run_0.bag+run_1.bag`` for pieces."""
    paths = [Path(path)] if isinstance(path, (str, os.PathLike)) else [Path(p) for p in path]
    return paths, paths[0] if len(paths) == 1 else paths[0].with_name("+".join(p.name for p in paths))


@contextmanager
def open_bag(path: str | os.PathLike | list) -> Iterator[_Source]:
    """Open a bag of any supported kind, or the pieces of a split recording as one (a list of ROS1 bags,
    or of .mcap / .db3 files); unreadable input raises ``InputError`` naming the file."""
    paths, name = run_files(path)
    for path in paths:
        if not path.exists():
            raise InputError("no such file or directory", path=path, remedy=_NOT_A_BAG)
        if path.is_file() and path.suffix not in (".bag", ".mcap", ".db3"):
            raise InputError(f"not a ROS bag (unknown extension {path.suffix!r})", path=path, remedy=_NOT_A_BAG)
        if path.is_dir() and not (path / "metadata.yaml").is_file():
            raise InputError("not a ROS2 bag directory (no metadata.yaml)", path=path, remedy=_NOT_A_BAG)
    stack = ExitStack()
    try:
        src = _open(paths, name, stack)
    except InputError:
        stack.close()
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags/mcap raise many types on corrupt input (MemoryError too)
        stack.close()
        raise InputError(f"not a readable ROS bag ({_cause(exc)})", path=name, remedy=_repair(name)) from None
    with stack:
        yield src


def _cause(exc: BaseException) -> str:
    """One line for an exception of a bag reader (a damaged length field often gives MemoryError)."""
    text = " ".join(str(exc).split())
    if isinstance(exc, (MemoryError, OverflowError)):
        text = "a length field is out of range" + (f": {text}" if text else "")
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _repair(path: Path) -> str:
    """What to do with a damaged container of ``path``'s kind."""
    if path.suffix == ".bag":
        how = "reindex it (rosbag reindex) or re-export it"
    elif path.suffix == ".mcap":
        how = "recover what is readable (mcap recover IN -o OUT) or re-export it"
    else:
        how = "re-export it (ros2 bag convert) or record it again"
    return f"the file is truncated or damaged: {how}"


def _open(paths: list[Path], name: Path, stack: ExitStack) -> _Source:
    from rosbags.highlevel import AnyReader

    for path in paths:
        if path.suffix != ".mcap":
            continue
        fh = stack.enter_context(open(path, "rb"))
        try:
            reader, summary = _mcap_ros1_summary(path, fh)
        except Exception:  # noqa: BLE001 - let rosbags try (it also scans unindexed files)
            reader, summary = None, None
        if reader is not None and len(paths) > 1:
            raise InputError("pieces of an MCAP recording with ROS1-encoded channels cannot be read as one run", path=path,
                             remedy=f"merge them into one file first (mcap merge {' '.join(p.name for p in paths)} -o ONE.mcap)")
        if reader is not None:
            return _McapRos1Source(path, fh, reader, summary)
    return _RosbagsSource(name, stack.enter_context(AnyReader(paths)))


# ---- split recordings ---------------------------------------------------------------------------
PIECE = re.compile(r"^(?P<stem>.+)_(?P<n>\d+)$")  # rosbag record --split: run_0.bag, run_1.bag, ...
CONTINUES = 1.0  # s: a piece of a split recording starts within this of the end of the piece before it


def runs_of(bags: list[Path], join: bool | None = None) -> list[tuple[Path, ...]]:
    """The runs of ``bags``: each bag alone, except the pieces of split recordings (``rosbag record --split``:
    files ``STEM_N`` of one directory and extension, N consecutive, each starting within ``CONTINUES`` s of
    the end of the one before), which ``join=True`` makes one run (pieces in the order of N, at the place of
    the first given). ``join=None`` refuses such pieces, naming ``--join`` and ``--no-join``; ``join=False``
    keeps every bag a run. With ``join=True``, files ``STEM_N`` that do not continue one another are refused."""
    if join is False:
        return [(b,) for b in bags]
    groups: dict[tuple, list[tuple[int, Path]]] = defaultdict(list)
    for b in bags:
        m = PIECE.match(b.stem) if b.is_file() else None
        if m:
            groups[(b.parent.resolve(), m["stem"], b.suffix)].append((int(m["n"]), b))
    run_of: dict[Path, tuple[Path, ...]] = {}
    for (_, stem, suffix), items in groups.items():
        items.sort()
        for (n0, a), (n1, b) in zip(items, items[1:]):
            if n1 == n0:
                raise InputError("bag given twice", path=b, remedy="give each bag once")
        spans = [_span(p) for _, p in items]
        for (n0, a), (n1, b), (_, end), (start, _) in zip(items, items[1:], spans, spans[1:]):
            gap = (start - end) * 1e-9
            what = (f"{b.name} starts {gap:.3g} s after {a.name} ends" if gap >= 0
                    else f"{b.name} starts {-gap:.3g} s before {a.name} ends")
            if join is None and n1 == n0 + 1 and abs(gap) <= CONTINUES:
                raise InputError(f"{a.name} and {b.name} are pieces of one split recording ({what})",
                                 path=a.parent, remedy="analyse them as one run with --join (or each as a run of its own "
                                                       "with --no-join)")
            if join and n1 != n0 + 1:
                raise InputError(f"--join: {stem}_{n0 + 1}{suffix} is missing between {a.name} and {b.name}", path=a.parent,
                                 remedy="give every piece of the recording")
            if join and abs(gap) > CONTINUES:
                raise InputError(f"--join: {a.name} and {b.name} are not pieces of one recording ({what})", path=a.parent,
                                 remedy="give --join the pieces of split recordings only (analyse the others in another call)")
        if join:
            run_of.update((b, tuple(p for _, p in items)) for _, b in items)
    runs = [run_of.get(b, (b,)) for b in bags]
    return [r for i, r in enumerate(runs) if len(r) == 1 or r not in runs[:i]]


def _span(path: Path) -> tuple[int, int]:
    """The record times (ns) of the first and last messages of a bag."""
    with open_bag(path) as src:
        return src.span


# ---- bag-info ---------------------------------------------------------------------------------
def bag_info(path: str | os.PathLike) -> tuple[list[dict], list[dict]]:
    """Per topic: type, count, first/last record time, rate; and the tf edges with their counts."""
    rows, edges = [], defaultdict(lambda: {"count": 0, "static": False})
    with open_bag(path) as src:
        topics = sorted(src.topics)
        first, last = {}, {}
        for topic, msgtype, ts, raw in _checked(src, topics, raw=True):  # only tf messages are decoded
            first[topic] = min(ts, first.get(topic, ts))
            last[topic] = max(ts, last.get(topic, ts))
            if msgtype == TF_TYPE:
                for tr in _decode(src, raw, msgtype).transforms:
                    e = edges[(_frame(tr.header.frame_id), _frame(tr.child_frame_id))]
                    e["count"] += 1
                    e["static"] |= topic.endswith("tf_static")
        for name in topics:
            t = src.topics[name]
            t0, t1 = first.get(name), last.get(name)
            n = t.count or 0
            span = (t1 - t0) / 1e9 if t0 is not None else 0.0
            rows.append({"topic": name, "type": t.msgtype.replace("/msg/", "/"), "count": n,
                         "start": t0 / 1e9 if t0 is not None else float("nan"),
                         "end": t1 / 1e9 if t1 is not None else float("nan"),
                         "rate": (n - 1) / span if n > 1 and span > 0 else float("nan"),
                         "pose": t.msgtype in SUPPORTED})
    return rows, [{"parent": p, "child": c, **v} for (p, c), v in sorted(edges.items())]


def _checked(src: _Source, topics, raw: bool = False) -> Iterator[tuple[str, str, int, object]]:
    """The messages of ``topics``; a reader's failure, or a record whose time is not an integer or
    whose data are not bytes (a damaged SQLite record), is an ``InputError``."""
    try:
        for item in (src.raw(topics) if raw else src.messages(topics)):
            if not isinstance(item[2], int) or (raw and not isinstance(item[3], (bytes, bytearray, memoryview))):
                raise InputError(f"cannot read the messages (a damaged record of {item[0]}: its time is "
                                 f"{type(item[2]).__name__}, its data {type(item[3]).__name__})", path=src.path,
                                 remedy=_repair(src.path))
            yield item
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001
        path = src.piece_at_fault(topics)
        raise InputError(f"cannot read the messages ({_cause(exc)})", path=path, remedy=_repair(path)) from None


# ---- pose streams -----------------------------------------------------------------------------
def _stamp(msg) -> float:
    """``sec + nanosec 1e-9``; NaN for a nanosec outside 0..1e9 (not a time: a damaged stamp)."""
    s = msg.header.stamp
    return s.sec + s.nanosec * 1e-9 if 0 <= s.nanosec < 1_000_000_000 else float("nan")


def _pose_of(msg, msgtype: str):
    if msgtype == "geometry_msgs/msg/TransformStamped":
        p, q = msg.transform.translation, msg.transform.rotation
    elif msgtype in ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseWithCovarianceStamped"):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
    else:
        p, q = msg.pose.position, msg.pose.orientation
    return (p.x, p.y, p.z), (q.x, q.y, q.z, q.w)


def read_streams(path: str | os.PathLike | list, specs: dict[str, PoseSpec], time: str = "header",
                 optional: tuple[str, ...] = (), sparse: tuple[str, ...] = (),
                 scale: dict[str, float] | None = None) -> dict[str, PoseStream]:
    """Read several pose streams in one pass over the bag (or over the pieces of a split recording, a list
    of paths, as one): ``{name: PoseStream}``; the names in
    ``optional`` are left out (instead of an error) when their topic is not in the bag; those in
    ``sparse`` (commands such as goals) are not checked for continuity (``_stream``); ``scale``: metres
    per unit of a stream's positions (0.001 for millimetres; 1 when not given), applied before the checks."""
    if time not in ("header", "record"):
        raise ValueError("time must be 'header' or 'record'")
    paths, path = run_files(path)
    scale = scale or {}
    fast = _indexed_streams(paths, specs, time, optional, sparse, scale)
    if fast is not None:
        return fast
    with open_bag(paths) as src:
        need = set()
        specs = {k: v for k, v in specs.items() if k not in optional or v.is_tf or v.topic in src.topics}
        missing = {k: v for k, v in specs.items() if not v.is_tf and v.topic not in src.topics}
        if missing:
            raise missing_topics(path, src, missing)
        for spec in specs.values():
            if spec.is_tf:
                present = [t for t in spec.tf_topics if t in src.topics]
                if spec.tf_topic not in src.topics:
                    others = sorted(t for t in src.topics if src.topics[t].msgtype == TF_TYPE and not t.endswith("_static"))
                    raise InputError(f"no topic {spec.tf_topic} for {spec}", path=path, remedy=(
                        f"tf topics in the bag: {', '.join(others)}: a frame pair on another topic is given as "
                        f"TOPIC:PARENT->CHILD (e.g. {others[0]}:{spec.parent}->{spec.child})" if others
                        else f"topics in the bag: {_topic_list(src)}"))
                for t in present:
                    if src.topics[t].msgtype != TF_TYPE:
                        raise InputError(f"topic {t} has message type {src.topics[t].msgtype.replace('/msg/', '/')}, "
                                         f"not {TF_TYPE.replace('/msg/', '/')}", path=path,
                                         remedy="a damaged bag, or tf recorded in another type: re-export it, or pass a pose "
                                                "topic (e.g. --icp /icp/pose)")
                need.update(present)
            else:
                mt = src.topics[spec.topic].msgtype
                if mt not in POSE_TYPES and mt != TF_TYPE:
                    raise InputError(f"topic {spec.topic} has message type {mt.replace('/msg/', '/')}, which holds no pose",
                                     path=path, remedy="use a PoseStamped, PoseWithCovarianceStamped, TransformStamped or Odometry topic, or tf:PARENT->CHILD")
                if mt == TF_TYPE:
                    raise InputError(f"topic {spec.topic} is a tf topic", path=path,
                                     remedy=f"ask for a frame pair on it: {spec.topic}:PARENT->CHILD")
                need.add(spec.topic)
        data: dict[str, np.ndarray] = {}
        static_topics = {t for spec in specs.values() if spec.is_tf for t in spec.tf_topics[1:]}
        tf: dict[tuple[str, str], list] = defaultdict(list)
        static: dict[tuple[str, str], tuple] = {}
        frame_ids: dict[str, str] = {}
        raws: dict[str, list] = defaultdict(list)
        stamps: dict[str, list] = defaultdict(list)
        for topic, msgtype, ts, raw in _checked(src, sorted(need), raw=True):
            if msgtype == TF_TYPE:
                for tr in _decode(src, raw, msgtype).transforms:
                    key = (_frame(tr.header.frame_id), _frame(tr.child_frame_id))
                    pose = _pose_of(tr, "geometry_msgs/msg/TransformStamped")
                    if topic in static_topics:
                        static[key] = pose
                    else:
                        tf[key].append((_stamp(tr) if time == "header" else ts * 1e-9, *pose[0], *pose[1], ts * 1e-9))
            else:
                raws[topic].append(raw)
                stamps[topic].append(ts)
        for topic, items in raws.items():
            msgtype = src.topics[topic].msgtype
            rows = _fast_rows(items, msgtype, src.ros1)
            if rows is None:  # layouts differ between messages: decode one by one
                msgs = [_decode(src, r, msgtype) for r in items]
                frame_ids[topic] = _frame(msgs[0].header.frame_id)
                rows = np.array([(_stamp(m), *_pose_of(m, msgtype)[0], *_pose_of(m, msgtype)[1]) for m in msgs], dtype=float)
            else:
                frame_ids[topic] = _frame(_decode(src, items[0], msgtype).header.frame_id)
            record = np.asarray(stamps[topic], dtype=np.int64) * 1e-9
            if time == "record":
                rows[:, 0] = record
            data[topic] = np.column_stack([rows, record])  # the record time beside each pose
    out = {}
    for name, spec in specs.items():
        if spec.is_tf:
            out[name] = _chain(path, spec, tf, static, scale.get(name, 1.0))
        else:
            rows = np.asarray(data.get(spec.topic, []), dtype=float).reshape(-1, 9)
            if len(rows) == 0:
                raise InputError(f"topic {spec.topic} has no messages", path=path, remedy=f"topics in the bag: {_topic_list_from(data)}")
            rows[:, 1:4] *= scale.get(name, 1.0)
            out[name] = _stream(path, str(spec), rows[:, :8], frame_ids.get(spec.topic, ""), continuous=name not in sparse,
                                record=rows[:, 8])
    return out


def _indexed_streams(path, specs: dict[str, PoseSpec], time: str, optional: tuple[str, ...],
                     sparse: tuple[str, ...], scale: dict[str, float] | None = None) -> dict[str, PoseStream] | None:
    """``read_streams`` through the bag's own index (``indexed``) when every stream is a pose topic of
    the bag whose messages share one layout (for pieces: each piece holds every stream, all of one layout,
    read one after the other); None otherwise (the general path then reads the bag)."""
    if any(spec.is_tf for spec in specs.values()):
        return None
    from cobot_analysis.localisation import indexed

    paths, path = run_files(path)
    bags = [indexed.open_indexed(p) for p in paths]
    if any(b is None or b.ros1 != bags[0].ros1 for b in bags):
        return None
    bag = bags[0]
    specs = {k: v for k, v in specs.items() if k not in optional or v.topic in bag.topics}
    topics = sorted({spec.topic for spec in specs.values()})
    if not all(bag.topics.get(t) in POSE_TYPES and all(b.topics.get(t) == bag.topics[t] for b in bags) for t in topics):
        return None
    parts = [b.read(topics) for b in bags]
    if any(p is None for p in parts) or any(len({p[t].data.shape[1] for p in parts}) > 1 for t in topics):
        return None
    messages = parts[0] if len(parts) == 1 else {
        t: indexed.Messages(np.concatenate([p[t].record_ns for p in parts]), np.concatenate([p[t].data for p in parts]))
        for t in topics}
    parts = None
    read = {}
    for name, spec in specs.items():
        msgtype, msgs = bag.topics[spec.topic], messages[spec.topic]
        got = _layout_rows(msgs.data, msgtype, bag.ros1)
        if got is None:
            return None
        rows, frame_id = got
        record = msgs.record_ns * 1e-9
        if time == "record":
            rows[:, 0] = record
        rows[:, 1:4] *= (scale or {}).get(name, 1.0)
        read[name] = (rows, frame_id, record)
    messages = msgs = None  # the serialised messages are no longer needed
    return {name: _stream(path, str(spec), read[name][0], _frame(read[name][1]), continuous=name not in sparse,
                          record=read[name][2]) for name, spec in specs.items()}


def _decode(src: _Source, raw, msgtype: str):
    try:
        return src.deserialize(raw, msgtype)
    except Exception as exc:  # noqa: BLE001
        path = src.piece_at_fault([t.name for t in src.topics.values() if t.msgtype == msgtype], decode=msgtype)
        raise InputError(f"cannot decode a {msgtype.replace('/msg/', '/')} message ({_cause(exc)})", path=path,
                         remedy=f"{_repair(path)}; or its message definition differs from the standard one") from None


# Fixed-layout decoding: pose messages of one topic usually have the same frame names and hence
# the same byte layout; then all stamps and poses are read at once with numpy views.
_CHILD = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/TransformStamped")


def _fast_rows(raws: list, msgtype: str, ros1: bool) -> np.ndarray | None:
    """``(n, 8)`` rows ``(t, x, y, z, qx, qy, qz, qw)`` decoded from the serialised messages when
    they all share one layout (ROS1 or little-endian CDR), else None."""
    size = len(raws[0])
    if any(len(r) != size for r in raws):
        return None
    got = _layout_rows(np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), size), msgtype, ros1)
    return None if got is None else got[0]


def _layout_rows(buf: np.ndarray, msgtype: str, ros1: bool) -> tuple[np.ndarray, str] | None:
    """``_fast_rows`` of the messages as the rows of ``buf`` ``(n, size)``, with the header's frame id
    (as read, before ``_frame``); None when they do not share one layout or the frame id is not text."""
    size = buf.shape[1]
    first = bytes(buf[0])
    base = 0 if ros1 else 4
    if not ros1 and first[1] != 1:  # CDR encapsulation: 0x0001 = little endian
        return None

    def u32(buf, k):
        return int.from_bytes(buf[k:k + 4], "little")

    stamp = base + (4 if ros1 else 0)  # ROS1 headers start with a sequence number
    strings = [stamp + 8]
    pos = stamp + 12 + u32(first, stamp + 8)
    if msgtype in _CHILD:
        if not ros1:
            pos = base + -(-(pos - base) // 4) * 4
        strings.append(pos)
        pos += 4 + u32(first, pos)
    if not ros1:
        pos = base + -(-(pos - base) // 8) * 8  # doubles are 8-aligned from the CDR origin
    if pos + 56 > size:
        return None
    for k in strings:  # every message must carry strings of the same lengths
        if not np.all(buf[:, k:k + 4] == buf[0, k:k + 4]):
            return None
    try:
        frame_id = first[strings[0] + 4:strings[0] + 4 + u32(first, strings[0])].decode().rstrip("\x00")
    except UnicodeDecodeError:
        return None
    rows = np.empty((len(buf), 8))
    rows[:, 1:] = buf[:, pos:pos + 56].view("<f8")  # (unaligned) views of the rows' bytes: no copies
    sec = buf[:, stamp:stamp + 4].view("<u4" if ros1 else "<i4")[:, 0]
    nsec = buf[:, stamp + 4:stamp + 8].view("<u4")[:, 0]
    rows[:, 0] = np.where(nsec < 1e9, sec + nsec * 1e-9, np.nan)  # as _stamp
    return rows, frame_id


#: the localisation options of each stream read from a bag, for messages.
STREAM_OPTIONS = {"truth": "--truth", "icp": "--icp", "goals": "--goal-topic"}
TRUTH_HINTS = ("mocap", "vicon", "qualisys", "optitrack", "truth", "ground", "/gt")


def missing_topics(path: Path, src: _Source, missing: dict[str, PoseSpec]) -> InputError:
    """The error for stream topics absent from a bag: it names the options (``--truth``, ``--icp``),
    lists the topics whose message type holds a pose, points at ``tf:PARENT->CHILD`` when the bag
    has tf, and, when exactly one (truth, ICP) pair is plausible (two pose topics besides goals, one of
    them named like motion capture: mocap, vicon, qualisys, optitrack, truth, ground, gt), the command
    line that uses it."""
    what = "; ".join(f"no topic {spec.topic} for {STREAM_OPTIONS.get(name, name)}" for name, spec in missing.items())
    poses = sorted((t for t in src.topics.values() if t.msgtype in POSE_TYPES), key=lambda t: t.name)
    found = ", ".join(f"{t.name} ({t.msgtype.replace('/msg/', '/')}, {t.count})" for t in poses) or "none"
    tf = [t for t in TF_TOPICS if t in src.topics]
    hints = [f"pose topics in the bag: {found}"]
    if tf:
        hints.append(f"the bag has {' and '.join(tf)}: a frame pair is given as tf:PARENT->CHILD (`cobot-analysis bag-info {path}` "
                     f"lists them)")
    candidates = [t.name for t in poses if "goal" not in t.name.lower()]  # commanded goals are poses, not a trajectory
    truth_like = [name for name in candidates if any(h in name.lower() for h in TRUTH_HINTS)]
    if len(candidates) == 2 and len(truth_like) == 1 and set(missing) <= {"truth", "icp"}:
        icp = next(name for name in candidates if name != truth_like[0])
        hints.append(f"run `cobot-analysis localisation {path} --truth {truth_like[0]} --icp {icp}`")
    else:
        hints.append("pass the streams with " + " and ".join(f"{STREAM_OPTIONS.get(n, n)} TOPIC" for n in missing))
    hints.append(f"all topics: {_topic_list(src)}")
    return InputError(what, path=path, remedy="; ".join(hints))


def _topic_list(src: _Source) -> str:
    return ", ".join(f"{t.name} ({t.msgtype.replace('/msg/', '/')}, {t.count})" for t in sorted(src.topics.values(), key=lambda t: t.name))


def _topic_list_from(data) -> str:
    return ", ".join(sorted(data)) or "none"


QUAT_TOL = 0.01  # |norm - 1| of a stored orientation quaternion beyond which the message is damaged
POSITION_LIMIT = 1000.0  # m: largest |x|, |y|, |z| of a pose in a lab or building frame
MAX_SPEED = 10.0  # m/s between consecutive poses: beyond this a pose is a jump (damage, tracking loss, relocalisation)
MAX_TURN = 10.0  # rad/s between consecutive orientations: beyond this likewise
STAMP_STEP = 0.5  # s: a stamp this far from the stamps before and after it in the bag (which agree) is out of place
CLOCK_JUMP = 10.0  # s: stamps of consecutive messages whose offsets to the bag's record times differ by more jump
MILLIMETRES = "or positions in millimetres: --units gives the unit of each stream (TRUTH,ICP, e.g. --units mm,m)"
DAMAGED = ("a damaged bag: re-export it or record it again (a stream that really glitched there: leave that message "
           "out of the bag, e.g. with rosbag filter)")


def _at(order: np.ndarray, n: int, t: np.ndarray, bad: np.ndarray) -> str:
    """'message 18 of 2813 (stamp 1634300000.085 s) and 2 more' for the first of the ``bad`` rows."""
    k = np.flatnonzero(bad)
    stamp = f" (stamp {t[k[0]]:.3f} s)" if np.isfinite(t[k[0]]) else ""
    return f"message {order[k[0]] + 1} of {n}{stamp}" + (f" and {len(k) - 1} more" if len(k) > 1 else "")


def _isolated(fast: np.ndarray, fast_over: np.ndarray) -> np.ndarray:
    """Interior samples whose steps to both neighbours are ``fast`` while the step over them is not
    (``fast[k]``: the step k -> k + 1, ``fast_over[k]``: k -> k + 2)."""
    out = np.zeros(len(fast) + 1, bool)
    out[1:-1] = fast[:-1] & fast[1:] & ~fast_over
    return out


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between unit quaternions, row by row."""
    return 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0.0, 1.0))


#: the share of a stream's orientation quaternions that must have one norm for it to be the publisher's (the others damaged)
CONSTANT_NORM_SHARE = 0.9


def _constant_norm(norm: np.ndarray) -> float:
    """The norm the orientation quaternions share (their median, when at least ``CONSTANT_NORM_SHARE`` of the norms lie
    within ``QUAT_TOL`` of it, relatively, and it is not within ``QUAT_TOL`` of 1: a publisher that never normalises;
    the others are damage), else 1."""
    if not len(norm):
        return 1.0
    m = float(np.median(norm))
    return m if abs(m - 1.0) > QUAT_TOL and np.mean(np.abs(norm / m - 1.0) <= QUAT_TOL) >= CONSTANT_NORM_SHARE else 1.0


def _stream(path: Path, name: str, rows: np.ndarray, frame_id: str = "", continuous: bool = True,
            record: np.ndarray | None = None) -> PoseStream:
    """Sorted, de-duplicated stream from rows ``(t, x, y, z, qx, qy, qz, qw)`` in the order read
    (``record``: the bag's record time of each, s; the median of stamp minus record time is kept in
    ``meta["clock"]``).

    Dropped with a warning (kept in ``meta["notes"]``): messages with NaN/inf (a lost rigid body), a
    zero quaternion (orientation unset) or a quaternion far from unit norm (from the norm all share, when
    they share one: ``_constant_norm``, normalised with a warning); repeated stamps. Sorted
    with a warning: unsorted stamps. Warned about: jumps faster than ``MAX_SPEED`` / ``MAX_TURN``
    (a relocalisation, or damage at an end of the stream). Refused (``InputError`` naming the
    message), as values no recording holds: a stamp whose nanosec is not below 1e9, a position
    beyond ``POSITION_LIMIT``; in a ``continuous`` stream (not the goals) most messages sharing one
    stamp (unstamped: --time record), a stamp whose offset to the
    record time jumps by more than ``CLOCK_JUMP`` from the message before, a stamp ``STAMP_STEP`` away
    from both its neighbours in the bag, an end stamp further from the others than they span, and
    an isolated spike (a pose leaving both neighbours faster than the limits while they agree).
    """
    notes, n_msgs = [], len(rows)
    order = np.arange(n_msgs)  # message index in the bag, through drops and sorting

    def note(text: str) -> None:
        notes.append(f"{name}: {text}")
        warn(f"{path}: {name}: {text}")

    def refuse(what: str, bad: np.ndarray, remedy: str = DAMAGED) -> None:
        if bad.any():
            raise InputError(f"{name}: {what} in {_at(order, n_msgs, rows[:, 0], bad)}", path=path, remedy=remedy)

    refuse("a stamp whose nanosec is not below 1e9", np.isnan(rows[:, 0]))
    if continuous and record is not None and len(rows) > 1:
        refuse(f"a stamp that jumps by more than {CLOCK_JUMP:g} s against the bag's record times",
               np.concatenate([[False], np.abs(np.diff(rows[:, 0] - record)) > CLOCK_JUMP]),
               remedy=f"{DAMAGED}; or a clock that jumped: analyse with the record times (--time record)")
    drops = []
    finite = np.isfinite(rows).all(axis=1)
    norm = row_norm(np.where(np.isfinite(rows[:, 4:8]), rows[:, 4:8], 0.0))
    zero = finite & (norm < 1e-9)
    unit = _constant_norm(norm[finite & ~zero])
    if unit != 1.0:
        note(f"every orientation quaternion has the norm {unit:.3g}, not 1 (a publisher that does not normalise them): "
             "normalised")
    skew = finite & ~zero & (np.abs(norm / unit - 1.0) > QUAT_TOL)
    for mask, what in ((~finite, "NaN/inf values"), (zero, "a zero orientation quaternion (orientation unset)"),
                       (skew, f"an orientation quaternion of norm far from 1 ({norm[skew].min() if skew.any() else 0:.3g}.."
                              f"{norm[skew].max() if skew.any() else 0:.3g}: damaged)")):
        if mask.any():
            drops.append(f"{int(mask.sum())} with {what}")
    keep = finite & ~zero & ~skew
    if drops:
        if not keep.any():
            raise InputError(f"{name}: no usable pose in {n_msgs} message(s) ({'; '.join(drops)})", path=path,
                             remedy="check the topic with `cobot-analysis bag-info` and the recording (or pick another topic)")
        note(f"{n_msgs - int(keep.sum())} of {n_msgs} message(s) dropped: {'; '.join(drops)}")
        rows, order = rows[keep], order[keep]
    refuse(f"a position beyond {POSITION_LIMIT:g} m from the frame origin ({np.abs(rows[:, 1:4]).max():.3g} m)",
           (np.abs(rows[:, 1:4]) > POSITION_LIMIT).any(axis=1), remedy=f"{DAMAGED}; {MILLIMETRES}")
    t = rows[:, 0]
    if continuous and len(rows) > 2:
        values, counts = np.unique(t, return_counts=True)
        if len(t) - len(values) > len(t) / 2:  # most messages repeat a stamp: the publisher does not stamp them
            mode = values[np.argmax(counts)]
            raise InputError(f"{name}: {len(t) - len(values) + 1} of {n_msgs} messages share the header stamp {mode:.3f} s"
                             + (" (unset)" if mode == 0 else ""), path=path,
                             remedy="the publisher does not stamp its poses: analyse with the bag's record times (--time record)")
        gap = np.abs(np.diff(t)) > STAMP_STEP
        refuse(f"a stamp out of place (more than {STAMP_STEP:g} s from the stamps of the messages before and after it)",
               _isolated(gap, np.abs(t[2:] - t[:-2]) > STAMP_STEP))
    if np.any(np.diff(t) < 0):
        note("stamps are not monotonic; sorted by stamp")
        sort = np.argsort(t, kind="stable")
        rows, order = rows[sort], order[sort]
        t = rows[:, 0]
    dup = np.concatenate([[False], np.diff(t) == 0])
    if dup.any():
        note(f"{int(dup.sum())} message(s) with a repeated stamp dropped")
        rows, order = rows[~dup], order[~dup]
        t = rows[:, 0]
    xyz, quat = rows[:, 1:4], normalise(rows[:, 4:8])
    if len(rows) > 1:  # speed and turn rate between consecutive poses
        dt = np.diff(t)
        speed = row_norm(np.diff(xyz, axis=0)) / dt
        turn = _turn(quat[1:], quat[:-1]) / dt
    if continuous and len(rows) > 2:
        lone = np.zeros(len(rows), bool)
        lone[0] = t[1] - t[0] > max(STAMP_STEP, t[-1] - t[1])
        lone[-1] = t[-1] - t[-2] > max(STAMP_STEP, t[-2] - t[0])
        refuse("a stamp far from all others (further from them than they span)", lone)
        dt2 = t[2:] - t[:-2]
        refuse(f"a position spike (to and from its neighbours faster than {MAX_SPEED:g} m/s)",
               _isolated(speed > MAX_SPEED, row_norm(xyz[2:] - xyz[:-2]) / dt2 > MAX_SPEED), remedy=f"{DAMAGED}; {MILLIMETRES}")
        refuse(f"an orientation spike (to and from its neighbours faster than {MAX_TURN:g} rad/s)",
               _isolated(turn > MAX_TURN, _turn(quat[2:], quat[:-2]) / dt2 > MAX_TURN))
    if len(rows) > 1:
        fast = (speed > MAX_SPEED) | (turn > MAX_TURN)
        if fast.any():
            note(f"{int(fast.sum())} jump(s) between consecutive poses faster than {MAX_SPEED:g} m/s or {MAX_TURN:g} rad/s "
                 f"(up to {speed.max():.3g} m/s, {turn.max():.3g} rad/s): a relocalisation, lost tracking or a damaged bag; "
                 "check the poses (poses.parquet)")
    clock = {} if record is None else {"clock": float(np.median(t - record[order]))}  # stamps minus record times, s
    return PoseStream(t.copy(), xyz.copy(), quat, name=name, frame_id=frame_id, meta={"notes": notes, **clock})


def _chain(path: Path, spec: PoseSpec, tf: dict, static: dict, scale: float = 1.0) -> PoseStream:
    """Pose of ``spec.child`` in ``spec.parent`` through the frame tree (see module docstring); ``scale``:
    metres per unit of the transforms' translations."""
    edges = set(tf) | set(static)
    graph = defaultdict(set)
    for p, c in edges:
        graph[p].add(c)
        graph[c].add(p)
    frames = sorted(graph)
    if spec.parent not in graph or spec.child not in graph:
        missing = [f for f in (spec.parent, spec.child) if f not in graph]
        raise InputError(f"tf frame(s) {', '.join(missing)} not in the bag", path=path,
                         remedy=f"frames in {' and '.join(spec.tf_topics)}: {', '.join(frames) or 'none'}")
    # Breadth-first search for the path parent -> ... -> child.
    prev = {spec.parent: None}
    queue = deque([spec.parent])
    while queue:
        f = queue.popleft()
        for g in sorted(graph[f]):
            if g not in prev:
                prev[g] = f
                queue.append(g)
    if spec.child not in prev:
        raise InputError(f"tf frames {spec.parent} and {spec.child} are not connected", path=path,
                         remedy=f"frames in {' and '.join(spec.tf_topics)}: {', '.join(frames)}; edges: "
                                + ", ".join(f"{p}->{c}" for p, c in sorted(edges)))
    hops = []
    f = spec.child
    while prev[f] is not None:
        hops.append((prev[f], f))
        f = prev[f]
    hops.reverse()
    dynamic = {}
    for a, b in hops:
        key = (a, b) if (a, b) in edges else (b, a)
        if key in tf:
            rows = np.asarray(tf[key], dtype=float)
            rows[:, 1:4] *= scale
            dynamic[key] = _stream(path, f"tf:{key[0]}->{key[1]}", rows[:, :8], record=rows[:, 8])
    if not dynamic:
        raise InputError(f"tf:{spec.parent}->{spec.child} is static (only /tf_static edges)", path=path,
                         remedy="pick a frame pair that moves, e.g. map->base_link")
    notes = [n for s in dynamic.values() for n in s.meta.get("notes", [])]
    base = min(dynamic.values(), key=len)
    t = base.t
    valid = np.ones(len(t), bool)
    for s in dynamic.values():
        valid &= (t >= s.t[0]) & (t <= s.t[-1])
    t = t[valid]
    p = np.zeros((len(t), 3))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    for a, b in hops:
        forward = (a, b) in edges
        key = (a, b) if forward else (b, a)
        if key in dynamic:
            ep, eq = _interpolate(dynamic[key], t)
        else:
            sp, sq = static[key]
            ep, eq = np.tile(np.asarray(sp, dtype=float) * scale, (len(t), 1)), np.tile(normalise(np.asarray(sq, dtype=float)), (len(t), 1))
        if not forward:
            ep, eq = invert(ep, eq)
        p, q = compose(p, q, ep, eq)
    clock = {"clock": base.meta["clock"]} if "clock" in base.meta else {}
    return PoseStream(t, p, normalise(q), name=str(spec), frame_id=spec.parent, meta={"notes": notes, **clock})


def _interpolate(s: PoseStream, t: np.ndarray):
    """Linear position and slerp orientation of ``s`` at ``t`` (inside its time range)."""
    if len(s) == 1:
        return np.tile(s.xyz[0], (len(t), 1)), np.tile(s.quat[0], (len(t), 1))
    i = np.clip(np.searchsorted(s.t, t, side="right"), 1, len(s) - 1)
    f = np.clip((t - s.t[i - 1]) / (s.t[i] - s.t[i - 1]), 0.0, 1.0)
    xyz = s.xyz[i - 1] + f[:, None] * (s.xyz[i] - s.xyz[i - 1])
    return xyz, slerp(s.quat[i - 1], s.quat[i], f)
