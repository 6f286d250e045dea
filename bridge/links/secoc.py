"""Authenticated host commands on CAN, in the style of AUTOSAR SecOC.

Classic CAN carries no sender identity, so without this any node on the bus
can send HALT, ACK or TRANSPORT and the robots obey (docs/protocol.md, "What
a node on the bus can and cannot do"). With a key file, every host command
(the DOWN kinds of firmware_logic/messages.py) is sealed: its payload is
followed by a freshness value (FV) and a truncated AES-128-CMAC over
(identifier, payload, full FV), filling the 8 data bytes:

    payload (n bytes) | FV, low 8-n-3 bytes, big-endian | MAC, 3 bytes

HALT and ACK (n = 1) carry the whole 32-bit FV, TRANSPORT (n = 3) its low
16 bits; the receiver rebuilds a truncated FV as the smallest value above
the last one it accepted from the host with those low bits. A frame is
passed on only when its MAC verifies and its FV is above the last accepted
one, so a forged, tampered or replayed command is counted and dropped.

Keys are per robot (a group key would let any robot forge the host), so a
broadcast command (node 0) is sent once per keyed robot, and a broadcast on
the bus is refused by the robots. The host keeps its counters across
restarts by reserving them in blocks of RESERVE in a small JSON file, written
before a reserved value is used: a restarted host starts above anything it
sent; the robots keep theirs the same way (seal_hello). A robot's HELLO
carries a MAC and its freshness floor, so the host confirms the key and
continues above what the robot took. TOUCH and HEARTBEAT stay plain; the
host validates them (docs/protocol.md, "Valid reports").
"""

from __future__ import annotations

import json
import logging
import os
import secrets
import stat
import tomllib
from pathlib import Path
from typing import Any, Callable

import can
from cryptography.hazmat.primitives.ciphers import Cipher
from cryptography.hazmat.primitives.ciphers.algorithms import AES
from cryptography.hazmat.primitives.ciphers.modes import ECB
from cryptography.hazmat.primitives.cmac import CMAC

from bridge.errors import BridgeError
from bridge.links.codec import BadFrames
from bridge.links.errors import LinkError
from firmware_logic import messages as msg

log = logging.getLogger(__name__)

MAC_BYTES = 3          # 24-bit MAC: SecOC profile 1's length
FV_MAX = 0xFFFFFFFF    # a 32-bit freshness counter per robot
RESERVE = 256          # host counters are persisted this many frames ahead
KEY_BYTES = 16         # AES-128
MAX_FILE = 64 * 1024   # a key or freshness file is never larger (127 keys: ~6 kB)

# what a robot counts when it drops a host command (BadFrames fault names)
UNAUTHENTICATED = "unauthenticated host command"
BAD_MAC = "bad MAC"
STALE = "stale freshness (replayed or reordered)"
UNKEYED = "host command for a node without a key"
LOCKED = "host command to a locked-out robot"
# what a keyed host counts when it drops a robot's HELLO
HELLO_BAD_MAC = "HELLO with a bad MAC"
HELLO_PLAIN = "HELLO without a MAC"
HELLO_UNKEYED = "HELLO from a node without a key"
LOCKED_NODE = "frame of a locked-out node"
# what a keyed host counts when it drops a robot's report (TOUCH, HEARTBEAT,
# a behaviour's own): docs/protocol.md "Authenticated robot reports"
REPORT_BAD_MAC = "report with a bad MAC"
REPORT_PLAIN = "report without a MAC"
REPORT_UNKEYED = "report from a node without a key"
REPORT_DUPLICATE = "duplicate report"
REPORT_BYTES = 4       # a sealed report's payload: 4 + 1 freshness byte + 3 MAC = 8

# Brute force: a 24-bit MAC is guessed in 2^23 trials on average. A robot
# counts the host commands to it that fail their MAC and, at LOCKOUT, takes
# no host command any more until it is restarted (an attacker's chance
# before that: LOCKOUT / 2^24); the host locks a node out after
# HELLO_LOCKOUT bad HELLOs once its key was confirmed. Two bad HELLOs from a
# node whose key was never confirmed are a key mismatch (the robots
# retransmit HELLO every 4 ticks until it is acknowledged).
LOCKOUT = 1024
HELLO_LOCKOUT = 16
MISMATCH_AFTER = 2
BLOCK = 8              # a HELLO names the robot's freshness floor in blocks of 256
RESYNC = 16            # ticks between a robot's HELLOs after stale host commands
WINDOW = 64            # blocks below the host's counter tried before a full search
# a sealed report's MAC is bound to H, the last host counter its robot took
# (in this run), and r, its count of reports since: the host tries H from
# the counters it sealed for that node, the newest REPORT_WINDOW of them
# (one AES call), then, once per node, the last 2 x RESERVE (a resumed host,
# whose first counter is up to RESERVE above the last one it sent before)
REPORT_WINDOW = 64


class SecocError(BridgeError):
    """An error of authenticated frames, in one line: a key or freshness file
    that cannot be used, a node's 32-bit freshness counter at its end (the
    node needs a new key), a message with no room for its seal."""


REKEY = ("rekey: `touchswarm keys new --out NEW.toml`, give NEW.toml to the robots "
         "and the host, and start without the old freshness file")


def _read_small(path: Path, what: str) -> bytes:
    """A regular file's bytes, at most MAX_FILE; a FIFO or device is refused
    before it is opened (a read could hang or never end); `private`: refuse a
    file others may read."""
    where = f"{what} {str(path)!r}"
    try:
        st = os.stat(path)
    except OSError as err:
        raise SecocError(f"{where}: {err.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise SecocError(f"{where}: not a regular file; expected the TOML written by "
                         "`touchswarm keys new`")
    if st.st_size > MAX_FILE:
        raise SecocError(f"{where}: {st.st_size} bytes; such a file is at most "
                         f"{MAX_FILE} bytes")
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_FILE + 1)
    except OSError as err:
        raise SecocError(f"{where}: {err.strerror}") from None
    if len(data) > MAX_FILE:
        raise SecocError(f"{where}: more than {MAX_FILE} bytes")
    return data


def _check_private(path: Path) -> None:
    """Refuse a key file that its group or others may read or write."""
    if os.name != "posix":
        return
    mode = os.stat(path).st_mode & 0o777
    if mode & 0o077:
        raise SecocError(f"key file {str(path)!r}: mode {mode:04o} lets others read it; "
                         f"keys must be private: chmod 600 {path}")


def down_kinds() -> set[int]:
    return {m[0] for m in msg.rows() if m[2] == msg.DOWN}


def fv_bytes(payload_len: int) -> int:
    """How many FV bytes fit beside a payload and the MAC in 8 bytes."""
    return min(4, 8 - payload_len - MAC_BYTES)


def check_layout() -> None:
    """Every host command must leave room for at least one FV byte."""
    for m in msg.rows():
        if m[2] == msg.DOWN and fv_bytes(msg.dlc(m[0])) < 1:
            raise SecocError(f"message {m[1]} ({msg.dlc(m[0])} bytes) leaves no room for "
                             f"the {MAC_BYTES}-byte MAC and a freshness byte")


_MASK128 = (1 << 128) - 1


class Cmac1:
    """AES-128-CMAC of messages shorter than one block, for one key: such a
    message is padded (0x80 0...) and XORed with the subkey K2, then
    encrypted once (RFC 4493); the cipher and K2 are made once per key, so
    a frame costs one AES call and no CMAC object (every MAC of this module
    covers at most 12 bytes). `many` computes one MAC per block in one call."""

    __slots__ = ("enc", "k2")

    def __init__(self, key: bytes) -> None:
        self.enc = Cipher(AES(key), ECB()).encryptor()
        k = int.from_bytes(self.enc.update(bytes(16)), "big")
        for _ in range(2):                        # L -> K1 -> K2
            k = ((k << 1) & _MASK128) ^ (0x87 if k >> 127 else 0)
        self.k2 = k

    def block(self, message: bytes) -> int:
        """The block to encrypt for `message` (< 16 bytes), as an integer."""
        return int.from_bytes(message + b"\x80" + bytes(15 - len(message)), "big") ^ self.k2

    def mac(self, message: bytes) -> bytes:
        return self.enc.update(self.block(message).to_bytes(16, "big"))[:MAC_BYTES]

    def report_block(self, head: int, h: int, r: int) -> int:
        """The block of a report's MAC (_report_message): `head` is the
        identifier and the sealed payload as one integer (6 bytes)."""
        return (head << 80 | (h & 0xFFFFFFFF) << 48 | (r & 0xFFFFFFFF) << 16 | 0x8000) ^ self.k2

    def report(self, head: int, h: int, r: int) -> bytes:
        return self.enc.update(self.report_block(head, h, r).to_bytes(16, "big"))[:MAC_BYTES]

    def many(self, blocks: list[int]) -> list[bytes]:
        out = self.enc.update(b"".join(b.to_bytes(16, "big") for b in blocks))
        return [out[i:i + MAC_BYTES] for i in range(0, len(out), 16)]


_CMACS: dict[bytes, Cmac1] = {}


def cmac1(key: bytes) -> Cmac1:
    c = _CMACS.get(key)
    if c is None:
        c = _CMACS[key] = Cmac1(key)
    return c


def reference_mac(key: bytes, message: bytes) -> bytes:
    """The truncated CMAC by the cryptography library (tests compare Cmac1 to it)."""
    c = CMAC(AES(key))
    c.update(message)
    return c.finalize()[:MAC_BYTES]


def _mac(key: bytes, arbitration_id: int, payload: bytes, fv: int) -> bytes:
    return cmac1(key).mac(arbitration_id.to_bytes(2, "big") + payload + fv.to_bytes(4, "big"))


def _hello_macs(key: bytes, arbitration_id: int, payload: bytes, blocks: range) -> bytes:
    """The truncated MACs of a HELLO for many floor blocks, in one AES-ECB
    call: (identifier, payload, block) is 10 bytes, one CMAC block, so
    CMAC = AES(key, padded message XOR K2) (RFC 4493); _mac for each would
    take 65,536 CMAC objects (a quarter second) for a full search."""
    enc = Cipher(AES(key), ECB()).encryptor()
    k = int.from_bytes(enc.update(bytes(16)), "big")
    for _ in range(2):                        # L -> K1 -> K2
        k = ((k << 1) & ((1 << 128) - 1)) ^ (0x87 if k >> 127 else 0)
    head = arbitration_id.to_bytes(2, "big") + payload
    pad = b"\x80" + bytes(16 - len(head) - 5)
    k2 = k.to_bytes(16, "big")
    mask = int.from_bytes(k2, "big")
    base = int.from_bytes(head + bytes(4) + pad, "big") ^ mask
    shift = 8 * len(pad)
    msgs = b"".join((base ^ (b << shift)).to_bytes(16, "big") for b in blocks)
    out = enc.update(msgs)
    return b"".join(out[i:i + MAC_BYTES] for i in range(0, len(out), 16))


def seal_hello(key: bytes, frame: can.Message, last: int) -> can.Message:
    """A robot's HELLO with keys: payload (4) | floor block, low byte (1) |
    MAC (3) over (identifier, payload, the whole block). The block is
    last >> 8, `last` the highest host counter the robot may have taken, so
    the host starts above it (after a robot restart, a lost freshness file,
    a next mission) and, from the MAC, knows the robot holds its key."""
    payload = bytes(frame.data)
    block = last >> BLOCK
    data = payload + bytes([block & 0xFF]) + _mac(key, frame.arbitration_id, payload, block)
    return can.Message(arbitration_id=frame.arbitration_id, is_extended_id=False, data=data,
                       dlc=len(data), timestamp=frame.timestamp)


def load_keys(path: Path) -> dict[int, bytes]:
    """{node: key} from a TOML key file ([keys] NODE = "32 hex digits"),
    private to its owner, one distinct non-zero key per node."""
    where = f"key file {str(path)!r}"
    data = _read_small(Path(path), "key file")
    _check_private(Path(path))
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise SecocError(f"{where}: not UTF-8 text; expected TOML from "
                         "`touchswarm keys new`") from None
    except tomllib.TOMLDecodeError as err:
        raise SecocError(f"{where}: not valid TOML: {err}") from None
    table = raw.get("keys")
    if not isinstance(table, dict) or not table:
        raise SecocError(f"{where}: no [keys] table; expected NODE = \"32 hex digits\" "
                         "lines from `touchswarm keys new`")
    keys: dict[int, bytes] = {}
    named: dict[int, str] = {}
    owner: dict[bytes, int] = {}
    for name, value in table.items():
        node = _node_id(name)
        if node is None:
            raise SecocError(f"{where}: key {name!r}: expected a node id 1..{msg.MAX_NODE}")
        if node in keys:
            raise SecocError(f"{where}: node {node} is given twice ({named[node]!r} and "
                             f"{name!r}); one key per node")
        key = b""
        if isinstance(value, str) and value.isascii():
            try:
                key = bytes.fromhex(value)
            except ValueError:
                pass
        if len(key) != KEY_BYTES:
            raise SecocError(f"{where}: node {name}: expected {2 * KEY_BYTES} hex digits "
                             "(an AES-128 key)")
        if not any(key):
            raise SecocError(f"{where}: node {name}: an all-zero key is no secret; make "
                             "keys with `touchswarm keys new`")
        if key in owner:
            raise SecocError(f"{where}: nodes {owner[key]} and {node} have the same key; "
                             "a shared key lets one robot forge the host to the other")
        keys[node], named[node], owner[key] = key, name, node
    return keys


def _node_id(name: str) -> int | None:
    """A node id 1..MAX_NODE written in ASCII digits, else None."""
    if not (name.isascii() and name.isdigit()) or len(name) > 4:
        return None
    n = int(name)
    return n if 1 <= n <= msg.MAX_NODE else None


def new_key_file(path: Path, nodes: list[int]) -> None:
    """Write fresh random keys for `nodes`, readable by the owner only;
    never overwrites (a key already on robots would be lost)."""
    lines = ["# touchswarm CAN authentication keys: one AES-128 key per robot.",
             "# Keep private: whoever holds a robot's key can command that robot.",
             "[keys]"]
    lines += [f'{n} = "{secrets.token_hex(KEY_BYTES)}"' for n in nodes]
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write("\n".join(lines) + "\n")


class FreshnessStore:
    """The host's counters, persisted RESERVE frames ahead (None: in memory
    only, for tests and single-process runs)."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.reserved: dict[int, int] = {}
        if path is not None and Path(path).exists():
            self.reserved = self._load(Path(path))

    @staticmethod
    def _load(path: Path) -> dict[int, int]:
        where = f"freshness file {str(path)!r}"
        keep = ("; delete it only if no command sealed with these keys was ever sent, "
                "else " + REKEY)
        try:
            raw = json.loads(_read_small(path, "freshness file").decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as err:
            raise SecocError(f"{where}: not JSON ({err}){keep}") from None
        if not isinstance(raw, dict):
            raise SecocError(f"{where}: expected an object of node: counter{keep}")
        out: dict[int, int] = {}
        for name, value in raw.items():
            node = _node_id(name)
            if node is None:
                raise SecocError(f"{where}: {name!r}: expected a node id 1..{msg.MAX_NODE}"
                                 f"{keep}")
            if node in out:
                raise SecocError(f"{where}: node {node} is given twice{keep}")
            if type(value) is not int or not 0 <= value <= FV_MAX:
                raise SecocError(f"{where}: node {name}: counter {json.dumps(value)}; "
                                 f"expected an integer 0..{FV_MAX}{keep}")
            out[node] = value
        return out

    def start(self, node: int) -> int:
        """The first counter this process may use for `node`."""
        return self.reserved.get(node, 0)

    def reserve(self, node: int, upto: int) -> None:
        self.reserved[node] = upto
        if self.path is None:
            return
        tmp = Path(f"{self.path}.tmp")
        with open(tmp, "w") as f:
            json.dump({str(k): v for k, v in sorted(self.reserved.items())}, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)


class Sealer:
    """The host's side: seals every host command; a broadcast becomes one
    sealed frame per keyed robot."""

    def __init__(self, keys: dict[int, bytes], store: FreshnessStore | None = None) -> None:
        check_layout()
        self.keys = keys
        self.store = store or FreshnessStore(None)
        self.down = down_kinds()
        self.fv = {n: self.store.start(n) for n in keys}
        spent = [n for n, fv in self.fv.items() if fv >= FV_MAX]
        if spent:
            raise SecocError(f"node {spent[0]}: freshness counter at its end "
                             f"({FV_MAX}) in {self.store.path}; {REKEY}")
        self.limit = dict(self.fv)
        self.hello_kind_len = msg.dlc(msg.HELLO)
        self.confirmed: set[int] = set()        # nodes whose HELLO MAC verified
        self.hello_failed: dict[int, int] = {}
        self.searched: set[int] = set()         # nodes given the one full search
        self.locked: set[int] = set()
        self.bad: BadFrames | None = None       # the transport's
        # reports: per node the (H, r) last accepted, the lowest H this host
        # takes (its first counter for the node: nothing from an earlier run),
        # the HELLO fields (a sealed TOUCH's power), failures since confirmed
        self.report_at: dict[int, tuple[int, int]] = {}
        self.report_last: dict[int, bytes] = {}     # the last report's bytes
        self.report_floor: dict[int, int] = {}
        self.hellos: dict[int, tuple] = {}
        self.nodes: Any = None                  # node -> HELLO fields known from elsewhere
        self.report_failed: dict[int, int] = {}
        self.report_searched: set[int] = set()
        self.resumed = False                    # a resumed host: see open_report
        self._layouts: dict[int, ReportLayout] = {}
        self._rows: list | None = None
        self._cmacs: dict[int, Cmac1] = {}

    def _count(self, fault: str, frame: can.Message) -> None:
        if self.bad is not None:
            self.bad.add(fault, frame)

    def open_hello(self, frame: can.Message, node: int) -> can.Message | None:
        """A robot's HELLO, verified and stripped to its plain layout, or None
        (counted). Moves the node's counter above the floor it names. Raises
        a LinkError when a node whose key was never confirmed fails
        MISMATCH_AFTER times."""
        data = bytes(frame.data)
        n = self.hello_kind_len
        key = self.keys.get(node)
        if key is None:             # with keys, an id the key file lacks is no robot
            self._count(HELLO_UNKEYED, frame)
            return None
        if len(data) != n + 1 + MAC_BYTES:
            if len(data) == n:
                self._hello_failed(node, frame, HELLO_PLAIN)
                return None
            return frame            # the decoder names a wrong length
        payload, low, tag = data[:n], data[n], data[n + 1:]
        block = self._find_block(key, frame.arbitration_id, payload, low, tag, node)
        if block is None:
            self._hello_failed(node, frame, HELLO_BAD_MAC)
            return None
        self.confirmed.add(node)
        if node not in self.hellos:     # the first HELLO fixes them (roster.py)
            self.hellos[node] = tuple(self._hello_struct().unpack(payload))
        floor = min(FV_MAX, ((block + 1) << BLOCK) - 1)
        if floor > self.fv[node]:
            if block > (self.fv[node] >> BLOCK) + 1:
                log.warning("robot %d has taken commands of this key file up to counter "
                            "%d, beyond this host's %d (%s): continuing above it", node, floor,
                            self.fv[node],
                            f"freshness file {self.store.path} lost or older?"
                            if self.store.path else "this host keeps no freshness file")
            self.fv[node] = floor
        return can.Message(arbitration_id=frame.arbitration_id, is_extended_id=False,
                           data=payload, dlc=n, timestamp=frame.timestamp)

    def _find_block(self, key, ident, payload, low, tag, node) -> int | None:
        """The robot's floor block: the one with low byte `low` whose MAC
        matches, tried from the most the robot can have seen (the host's
        counter + one block) down WINDOW blocks; once per node, failing that,
        every block (a host that lost its freshness file)."""
        top = (self.fv[node] >> BLOCK) + 1
        b = top - ((top - low) & 0xFF)
        for _ in range(WINDOW):
            if b < 0:
                break
            if secrets.compare_digest(_mac(key, ident, payload, b), tag):
                return b
            b -= 256
        if node in self.searched:
            return None
        self.searched.add(node)
        blocks = range(low, (FV_MAX >> BLOCK) + 1, 256)
        macs = _hello_macs(key, ident, payload, blocks)
        best = None
        at = macs.find(tag)
        while at >= 0:            # the highest: starting too high only skips counters
            if at % MAC_BYTES == 0:
                best = blocks[at // MAC_BYTES]
            at = macs.find(tag, at + 1)
        return best

    def _hello_failed(self, node: int, frame: can.Message, fault: str) -> None:
        self._count(fault, frame)
        k = self.hello_failed[node] = self.hello_failed.get(node, 0) + 1
        if node not in self.confirmed:
            if k >= MISMATCH_AFTER:
                if fault == HELLO_PLAIN:
                    raise LinkError(f"robot {node} sends HELLO without a MAC: it has no key "
                                    "file; give `touchswarm robots` the same --keys FILE "
                                    "as the host")
                raise LinkError(f"robot {node}'s MAC fails with this key file: host and "
                                "robots have different key files")
        elif k >= HELLO_LOCKOUT:
            self._lock_out(node, k, "HELLOs failed authentication after its key was confirmed")

    def _next_fv(self, node: int) -> int:
        fv = self.fv[node] + 1
        if fv > FV_MAX:
            raise SecocError(f"node {node}: freshness counter exhausted ({FV_MAX} "
                             f"commands sealed with its key); {REKEY}")
        if fv > self.limit[node]:
            self.limit[node] = min(FV_MAX, fv + RESERVE)
            self.store.reserve(node, self.limit[node])
        self.fv[node] = fv
        return fv

    def seal(self, frame: can.Message) -> list[can.Message]:
        kind, node = msg.split_id(frame.arbitration_id)
        if kind not in self.down:
            return [frame]
        nodes = sorted(self.keys) if node == msg.HOST else [node]
        out = []
        for n in nodes:
            key = self.keys.get(n)
            if key is None:
                log.warning("no key for node %d: command %d not sent", n, kind)
                continue
            ident = msg.can_id(kind, n)
            payload = bytes(frame.data)
            fv = self._next_fv(n)
            if n not in self.report_floor:
                self.report_floor[n] = fv
            k = fv_bytes(len(payload))
            data = payload + (fv & ((1 << (8 * k)) - 1)).to_bytes(k, "big") + \
                _mac(key, ident, payload, fv)
            out.append(can.Message(arbitration_id=ident, is_extended_id=False, data=data,
                                   dlc=len(data), timestamp=frame.timestamp))
        return out


    # -- robot reports ----------------------------------------------------------

    def _hello_struct(self):
        from bridge.links.codec import struct_for
        return struct_for(msg.spec(msg.HELLO))

    def layout(self, kind: int) -> ReportLayout:
        if self._rows is None or msg.ACTIVE != self._rows:
            self._layouts, self._rows = report_layouts(), list(msg.ACTIVE)
        return self._layouts[kind]

    def hello_of(self, node: int) -> tuple | None:
        """The node's HELLO fields: from the resumed journal (`nodes`, the
        coordinator's record), else its first verified HELLO."""
        if self.nodes is not None:
            got = self.nodes.get(node)
            if got is not None:
                return tuple(got)
        return self.hellos.get(node)

    def open_report(self, frame: can.Message, node: int) -> tuple | None:
        """A sealed report's plain fields, verified and fresh, or None
        (counted). H is found among the counters this host sealed for the
        node, r from its low byte as the smallest above the last one taken
        under that H (so a replayed or reordered report reads as a later one
        and fails its MAC, as a replayed TRANSPORT does at a robot): the
        last accepted H first (the robot took nothing since), then
        the newest REPORT_WINDOW; a resumed host, once per node, also the
        2 x RESERVE below its first counter (its predecessor's last ones)."""
        c = self._cmacs.get(node)
        if c is None:
            key = self.keys.get(node)
            if key is None:
                self._count(REPORT_UNKEYED, frame)
                return None
            c = self._cmacs[node] = cmac1(key)
        data = frame.data
        if len(data) != 8:
            self._count(REPORT_PLAIN, frame)
            return None
        whole = int.from_bytes(data, "big")
        low = (whole >> 24) & 0xFF
        tag = data[REPORT_BYTES + 1:]
        ident = frame.arbitration_id
        head = ident << 32 | whole >> 32
        at = self.report_at.get(node)
        found = None
        if at is not None:
            h, r = at
            r = (r & ~0xFF) | low
            if r <= at[1]:
                r += 256
            # c.report, inlined: this is every keyed report's cost
            block = (head << 80 | h << 48 | (r & 0xFFFFFFFF) << 16 | 0x8000) ^ c.k2
            if secrets.compare_digest(c.enc.update(block.to_bytes(16, "big"))[:MAC_BYTES],
                                      tag):
                found = (h, r)
        if found is None:
            top = self.fv[node]
            bottom = self.report_floor.get(node, top + 1)
            if at is not None:
                bottom = max(bottom, at[0] + 1)
            if self.resumed and node not in self.report_searched:
                self.report_searched.add(node)
                bottom = min(bottom, max(0, self.store.start(node) - 2 * RESERVE))
            else:
                bottom = max(bottom, top - REPORT_WINDOW + 1)
            found = self._find_h(c, head, low or 256, bytes(tag), top, bottom)
        if found is None:
            if data == self.report_last.get(node):
                # the last report again (a bus or link duplicate, or a
                # replay of it): dropped, not held against the node
                self._count(REPORT_DUPLICATE, frame)
                return None
            self._report_failed(node, frame, REPORT_BAD_MAC)
            return None
        if self._rows is None or msg.ACTIVE != self._rows:
            self._layouts, self._rows = report_layouts(), list(msg.ACTIVE)
        hello = self.hellos.get(node) if self.nodes is None else self.hello_of(node)
        fields = self._layouts[ident >> 7].open(data, hello)
        if fields is None:
            self._report_failed(node, frame, REPORT_BAD_MAC)
            return None
        self.report_at[node] = found
        self.report_last[node] = bytes(data)
        return fields

    @staticmethod
    def _find_h(c: Cmac1, head: int, r: int, tag: bytes, top: int,
                bottom: int) -> tuple[int, int] | None:
        """(H, r) for the newest H in bottom..top whose MAC matches, in one AES call."""
        if bottom > top:
            return None
        hs = range(top, bottom - 1, -1)
        macs = c.many([c.report_block(head, h, r) for h in hs])
        for h, m in zip(hs, macs):
            if secrets.compare_digest(m, tag):
                return h, r
        return None

    def _report_failed(self, node: int, frame: can.Message, fault: str) -> None:
        self._count(fault, frame)
        if node in self.report_at:       # only once the node's reports verified
            k = self.report_failed[node] = self.report_failed.get(node, 0) + 1
            if k >= LOCKOUT:
                self._lock_out(node, k, "reports failed authentication")

    def _lock_out(self, node: int, k: int, what: str) -> None:
        """Past a lockout threshold: the node's frames are dropped from now on
        (said once)."""
        if node not in self.locked:
            self.locked.add(node)
            log.warning("robot %d: %d %s (forgery or brute force on its identifier): node "
                        "locked out, its frames are dropped from now on", node, k, what)


class Opener:
    """The robots' side: passes on a host command only when it verifies and
    is fresh, stripped back to its plain layout; anything else is counted in
    `bad` and dropped. Frames of other kinds pass unchanged."""

    def __init__(self, keys: dict[int, bytes], bad, store: FreshnessStore | None = None,
                 lockout: int = LOCKOUT) -> None:
        check_layout()
        self.keys = keys
        self.bad = bad
        self.down = down_kinds()
        # the robots' counters survive a restart: a robot reserves RESERVE
        # above what it takes and, restarted, refuses everything up to there
        self.store = store or FreshnessStore(None)
        self.last = {n: self.store.start(n) for n in keys}
        self.limit = dict(self.last)
        self.lockout = lockout
        self.failed = {n: 0 for n in keys}       # host commands whose MAC failed
        self.locked: set[int] = set()
        # nodes that got a genuine but stale command: the host may have lost
        # its counters (restarted without its freshness file), so the robot
        # says HELLO again, which names its floor (Gateway, every RESYNC ticks)
        self.stale: set[int] = set()
        # reports: H, the last host counter each robot took in this run (-1:
        # none yet, its reports are held back), and r, its reports since
        self.h = {n: -1 for n in keys}
        self.r = {n: 0 for n in keys}
        self.held_back = 0           # reports not sent: no host command taken yet
        self._layouts: dict[int, ReportLayout] = {}
        self._rows: tuple = ()

    def seal_report(self, node: int, kind: int, fields: tuple) -> can.Message | None:
        """A robot's report (not HELLO) sealed: the sealed payload (4) | r's
        low byte | MAC (3) over (identifier, payload, H, r). None before the
        robot took a host command in this run (held back: without H the host
        could not tell the report from a replay of an earlier run)."""
        key = self.keys.get(node)
        if key is None:
            return None
        h = self.h[node]
        if h < 0:
            self.held_back += 1
            return None
        layout = self._layout(kind)
        r = self.r[node] = self.r[node] + 1
        payload = layout.seal(fields)
        ident = msg.can_id(kind, node)
        data = payload + bytes([r & 0xFF]) + cmac1(key).mac(_report_message(ident, payload, h, r))
        return can.Message(arbitration_id=ident, is_extended_id=False, data=data, dlc=8)

    def _layout(self, kind: int) -> "ReportLayout":
        rows = tuple(msg.ACTIVE)
        if rows != self._rows:
            self._layouts, self._rows = report_layouts(), rows
        return self._layouts[kind]

    def hello(self, frame: can.Message) -> can.Message:
        """A robot's HELLO sealed (seal_hello) with its key and its floor."""
        node = msg.split_id(frame.arbitration_id)[1]
        key = self.keys.get(node)
        return frame if key is None else seal_hello(key, frame, self.last[node])

    def open(self, frame: can.Message) -> can.Message | None:
        if frame.is_extended_id or frame.is_remote_frame or frame.is_error_frame:
            return frame        # the decoder names these
        kind, node = msg.split_id(frame.arbitration_id)
        if kind not in self.down:
            return frame
        n = msg.dlc(kind)
        k = fv_bytes(n)
        data = bytes(frame.data)
        if node == msg.HOST or len(data) != n + k + MAC_BYTES:
            self.bad.add(UNAUTHENTICATED, frame)
            return None
        key = self.keys.get(node)
        if key is None:
            self.bad.add(UNKEYED, frame)
            return None
        if node in self.locked:
            self.bad.add(LOCKED, frame)
            return None
        payload, low = data[:n], int.from_bytes(data[n:n + k], "big")
        last = self.last[node]
        if k == 4:
            fv = low
        else:
            span = 1 << (8 * k)
            fv = (last & ~(span - 1)) | low
            if fv <= last:
                fv += span
        if not secrets.compare_digest(_mac(key, frame.arbitration_id, payload, fv),
                                      data[n + k:]):
            self.bad.add(BAD_MAC, frame)
            self.failed[node] += 1
            if self.failed[node] >= self.lockout:
                self.locked.add(node)
                log.warning("robot %d: %d host commands failed their MAC (forgery or brute "
                            "force): locked out, it takes no host command until restarted",
                            node, self.failed[node])
            return None
        if fv <= last:
            self.bad.add(STALE, frame)
            self.stale.add(node)
            return None
        self.last[node] = fv
        self.h[node] = fv
        self.r[node] = 0
        if fv > self.limit[node]:
            self.limit[node] = min(FV_MAX, fv + RESERVE)
            self.store.reserve(node, self.limit[node])
        return can.Message(arbitration_id=frame.arbitration_id, is_extended_id=False,
                           data=payload, dlc=n, timestamp=frame.timestamp)


# -- robot reports (docs/protocol.md, "Authenticated robot reports") -----------

class ReportLayout:
    """How one report kind is sealed: its plain row (messages.rows()) and its
    4-byte sealed fields (messages.SEALED, or derived: each Q8 field in whole
    units). `seal` maps plain fields to the sealed payload (robot side),
    `open` the payload back to plain fields (host side), taking a field the
    sealed form lacks from the node's HELLO (by name) or 0."""

    def __init__(self, row: tuple, sealed: tuple | None, hello: tuple) -> None:
        import struct
        plain = [f[0] for f in row[4]]
        if sealed is None:
            sealed = tuple((f[0], 1 if f[3] == 256 else f[1], f[2], 1) + tuple(f[4:])
                           for f in row[4])
        self.name = row[1]
        self.sealed = sealed
        size = sum(f[1] for f in sealed)
        if size > REPORT_BYTES:
            raise SecocError(f"message {row[1]}: its sealed form takes {size} bytes; a sealed "
                             f"report carries {REPORT_BYTES} beside its freshness byte and MAC")
        codes = {(1, 0): "B", (1, 1): "b", (2, 0): "H", (2, 1): "h"}
        self.st = struct.Struct("<" + "".join(codes[(f[1], f[2])] for f in sealed)
                                + "x" * (REPORT_BYTES - size))
        names = [f[0] for f in sealed]
        self.near = names.index("near") if "near" in names else -1
        self.take: list[tuple] = []       # per sealed field: (plain index, divisor ratio)
        for f in sealed:
            if f[0] == "near":
                self.take.append((-1, 1))
                continue
            i = plain.index(f[0])
            self.take.append((i, row[4][i][3] // f[3]))
        hello_names = [f[0] for f in hello]
        self.give: list[tuple] = []       # per plain field: (how, index, ratio)
        for i, name in enumerate(plain):
            if name in names:
                j = names.index(name)
                self.give.append(("s", j, self.take[j][1]))
            elif self.near >= 0 and name in ("rx", "ry"):
                self.give.append(("n", names.index("s" + name[1]), 0 if name == "rx" else 1))
            elif name in hello_names:
                self.give.append(("h", hello_names.index(name), 1))
            else:
                self.give.append(("z", 0, 0))
        self.plain = plain
        self._compile()

    def seal(self, f: tuple) -> bytes:
        vals = []
        for i, ratio in self.take:
            if i < 0:
                d = (f[self.plain.index("rx")] - f[self.plain.index("sx")],
                     f[self.plain.index("ry")] - f[self.plain.index("sy")])
                vals.append(msg.NEAR.index(d) if d in msg.NEAR else 255)
            else:
                vals.append((f[i] + ratio // 2) // ratio if ratio > 1 else f[i])
        return self.st.pack(*vals)

    def _compile(self) -> None:
        """`open(data, hello)`: the plain fields of a sealed report (its first
        4 bytes in `data`), or None: a `near` out of range, or a field from a
        HELLO the host does not know. Generated once per layout from `give`
        (a frame then costs one unpack and one tuple, no loop)."""
        parts = []
        for how, j, k in self.give:
            if how == "s":
                parts.append(f"g[{j}] * {k}" if k != 1 else f"g[{j}]")
            elif how == "n":
                parts.append(f"g[{j}] + N[g[{self.near}]][{k}]")
            elif how == "h":
                parts.append(f"h[{j}]")
            else:
                parts.append("0")
        checks = []
        if self.near >= 0:
            checks.append(f"    if g[{self.near}] >= {len(msg.NEAR)}:\n        return None\n")
        if any(how == "h" for how, _, _ in self.give):
            checks.append("    if h is None:\n        return None\n")
        src = ("def open(data, h):\n    g = unpack(data)\n" + "".join(checks)
               + f"    return ({', '.join(parts)},)\n")
        space: dict[str, Any] = {"N": msg.NEAR, "unpack": self.st.unpack_from}
        exec(compile(src, f"<sealed {self.name}>", "exec"), space)
        self.open: Callable[[bytes | bytearray, tuple | None], tuple | None] = space["open"]


def report_layout(row: tuple) -> ReportLayout:
    """The sealed layout of the report `row` (not HELLO): messages.SEALED's
    or derived; SecocError when it does not fit."""
    explicit = {k: fields for k, fields in msg.SEALED}
    return ReportLayout(row, explicit.get(row[0]), msg.spec(msg.HELLO)[4])


def report_layouts() -> dict[int, ReportLayout]:
    """The sealed layout of every report kind in use but HELLO (which has its
    own, seal_hello); SecocError when one does not fit."""
    return {row[0]: report_layout(row)
            for row in msg.rows() if row[2] == msg.UP and row[0] != msg.HELLO}


def keyed_layout(row: tuple) -> tuple[tuple, int, int] | None:
    """How a message travels on a keyed bus, as this module seals it: (payload
    fields, payload bytes, freshness bytes); MAC_BYTES of MAC follow, and the
    freshness value's low bytes and the MAC are big-endian. A host command:
    its plain fields and fv_bytes (Sealer.seal); HELLO: its plain fields and
    the floor block's low byte (seal_hello); any other report: its sealed
    fields in REPORT_BYTES and r's low byte (seal_report). `row` is a row of
    messages.rows() or of a behaviour's spec.MESSAGES; None: never sealed (a
    capture frame). The DBC of a keyed bus (bridge/links/dbc.py) is made
    from this."""
    kind, _name, direction = row[:3]
    if direction == msg.DOWN or (direction == msg.UP and kind == msg.HELLO):
        fields = tuple(row[4])
        n = sum(f[1] for f in fields)
    elif direction == msg.UP:
        fields, n = report_layout(row).sealed, REPORT_BYTES
    else:
        return None
    return fields, n, fv_bytes(n)


def _report_message(ident: int, payload: bytes, h: int, r: int) -> bytes:
    """What a report's MAC covers: identifier, sealed payload, the robot's
    last host counter H and its report count r under H (4 bytes each): 14
    bytes, one CMAC block."""
    return ident.to_bytes(2, "big") + payload + h.to_bytes(4, "big") + \
        (r & 0xFFFFFFFF).to_bytes(4, "big")
