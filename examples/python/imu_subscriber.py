#!/usr/bin/env python3
"""Print the samples a running imud publishes over iceoryx2 shared memory.

A minimal subscriber in Python, using the `iceoryx2` package from PyPI (the version must match
the iceoryx2 crate imud is built with, see requirements-dev.txt). It opens the same services as
`imu-echo`:

    imud/<name>/corrected   CorrectedSample  (type name "imud::CorrectedSample.v1")
    imud/<name>/raw         RawSample        (type name "imud::RawSample.v2"), with --raw
    imud/<name>/event       wakes subscribers when the daemon has published

The ctypes Structures below mirror the `#[repr(C)]` layouts documented in
crates/imu-rec/src/sample.rs field for field; iceoryx2 refuses to connect when the type name,
size or alignment differ, so a layout change on the Rust side shows up as an error here.

Usage:
    python3 examples/python/imu_subscriber.py [--name default] [--raw] [--count N]
                                              [--format text|jsonl] [--timeout SECONDS]
                                              [--publisher-user USER ...] [--socket PATH]

With --socket PATH it reads imud's readers' socket instead (e.g. /run/imud/<name>/readers.sock,
for a process of another user in imud's readers' group; iceoryx2's segments are imud's user's
alone) and needs no iceoryx2 package: one packet per recv, a 16-byte header ("IMRD", version 1,
stream code, packets imud could not queue for this reader) and the record's bytes in the same C
layout. It checks the server's uid with SO_PEERCRED against the same trusted users.

Before it prints anything it checks who created each service (the owner of the service's static
config under iceoryx2's root path, the check `imu-echo` makes): root, its own user, the user
`imud`, or those named by --publisher-user; another user's services are refused.

With --format jsonl every sample is one JSON object with the Rust field names (units included,
e.g. "accel_m_s2") plus "stream"; NaN and infinities are printed as null.
"""

import argparse
import ctypes
import hashlib
import json
import math
import os
import pwd
import sys
import time

import socket
import struct

try:
    import iceoryx2 as iox2
except ImportError:  # only the shared-memory mode needs it
    iox2 = None


class RawSample(ctypes.Structure):
    """One decoded data frame as the device sent it (imud::RawSample.v2, 176 bytes)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("t_device_ns", ctypes.c_uint64),
        ("t_host_monotonic_ns", ctypes.c_uint64),
        ("t_host_wall_ns", ctypes.c_uint64),
        ("t_sample_ns", ctypes.c_uint64),
        ("ticks_unwrapped", ctypes.c_uint64),
        ("accel_counts", ctypes.c_int32 * 3),
        ("gyro_counts", ctypes.c_int32 * 3),
        ("mag_counts", ctypes.c_int32 * 3),
        # 4 bytes of padding here (offset 84), inserted by ctypes exactly as by the C compiler.
        ("temp_c", ctypes.c_double),
        ("ticks", ctypes.c_uint16),
        ("command", ctypes.c_uint8),
        ("reserved", ctypes.c_uint8),
        ("flags", ctypes.c_uint32),
        ("accel_device_m_s2", ctypes.c_double * 3),
        ("gyro_device_rad_s", ctypes.c_double * 3),
        ("mag_device_gauss", ctypes.c_double * 3),
    ]

    @classmethod
    def type_name(cls) -> str:
        """The iceoryx2 type name shared with the Rust side."""
        return "imud::RawSample.v2"


class CorrectedSample(ctypes.Structure):
    """One sample in SI units with the calibration applied (imud::CorrectedSample.v1, 128 bytes)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("t_sample_ns", ctypes.c_uint64),
        ("t_wall_ns", ctypes.c_uint64),
        ("t_device_ns", ctypes.c_uint64),
        ("accel_m_s2", ctypes.c_double * 3),
        ("gyro_rad_s", ctypes.c_double * 3),
        ("mag_gauss", ctypes.c_double * 3),
        ("temp_c", ctypes.c_double),
        ("calibration_id", ctypes.c_uint64),
        ("flags", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
    ]

    @classmethod
    def type_name(cls) -> str:
        """The iceoryx2 type name shared with the Rust side."""
        return "imud::CorrectedSample.v1"


# The same layout guards as the Rust side: a mismatch here is a bug in this file.
assert ctypes.sizeof(RawSample) == 176 and ctypes.alignment(RawSample) == 8
assert RawSample.accel_device_m_s2.offset == 104 and RawSample.mag_device_gauss.offset == 152
assert RawSample.temp_c.offset == 88 and RawSample.flags.offset == 100
assert ctypes.sizeof(CorrectedSample) == 128 and ctypes.alignment(CorrectedSample) == 8
assert CorrectedSample.temp_c.offset == 104 and CorrectedSample.reserved.offset == 124

# Open errors that mean "not there yet": keep retrying until --timeout.
NOT_YET = {"DoesNotExist", "IsMarkedForDestruction", "HangsInCreation"}


def to_dict(sample: ctypes.Structure) -> dict:
    """The sample's fields by their Rust names; arrays become lists, non-finite floats None."""

    def plain(value):
        if isinstance(value, ctypes.Array):
            return [plain(v) for v in value]
        if isinstance(value, float) and not math.isfinite(value):
            return None
        return value

    return {name: plain(getattr(sample, name)) for name, _ in sample._fields_}


def num(value: float, decimals: int) -> str:
    """Fixed-point with a sign, or an exponent for values too large or small for it."""
    tiny = 0.5 * 10.0**-decimals
    if math.isfinite(value) and value != 0.0 and not tiny <= abs(value) < 1e7:
        return f"{value:+.3e}"
    return f"{value:+.{decimals}f}"


def as_text(stream: str, s) -> str:
    """One human-readable line."""
    if stream == "corrected":
        acc = " ".join(num(v, 4) for v in s.accel_m_s2)
        gyr = " ".join(num(v, 5) for v in s.gyro_rad_s)
        return (
            f"corrected seq={s.seq} t={s.t_sample_ns / 1e9:.6f}s accel[m/s^2]={acc} "
            f"gyro[rad/s]={gyr} temp={s.temp_c:.2f}C flags={s.flags:#x}"
        )
    acc = " ".join(f"{v:6d}" for v in s.accel_counts)
    gyr = " ".join(f"{v:6d}" for v in s.gyro_counts)
    return (
        f"raw       seq={s.seq} t={s.t_sample_ns / 1e9:.6f}s accel[counts]={acc} "
        f"gyro[counts]={gyr} ticks={s.ticks} flags={s.flags:#x}"
    )


def open_with_retry(open_fn, service: str, name: str, deadline: float):
    """Calls open_fn until the service exists or the deadline passes."""
    while True:
        try:
            return open_fn()
        except (iox2.PublishSubscribeOpenError, iox2.EventOpenError) as e:
            reason = e.args[0] if e.args else str(e)
            if reason not in NOT_YET:
                raise SystemExit(f"imu_subscriber: cannot open {service}: {reason}")
            if time.monotonic() >= deadline:
                raise SystemExit(
                    f"imu_subscriber: no imud instance named {name!r} is running "
                    f"({service} did not appear); start imud or pass its --name"
                )
            time.sleep(0.05)


def trusted_uids(users: list) -> set:
    """The uids of --publisher-user (names or numbers), or root, this user and `imud`."""
    if users:
        uids = set()
        for u in users:
            try:
                uids.add(int(u) if u.isdigit() else pwd.getpwnam(u).pw_uid)
            except KeyError:
                raise SystemExit(f"imu_subscriber: --publisher-user {u}: no such user")
        return uids
    uids = {0, os.geteuid()}
    try:
        uids.add(pwd.getpwnam("imud").pw_uid)
    except KeyError:
        pass
    return uids


def user_name(uid: int) -> str:
    """`user NAME (uid N)`, or `uid N` for an unknown uid."""
    try:
        return f"user {pwd.getpwuid(uid).pw_name} (uid {uid})"
    except KeyError:
        return f"uid {uid}"


def check_creator(service: str, pattern: int, trusted: set) -> None:
    """Refuses a service whose static config another user owns. Its file name is iceoryx2's
    hash of the messaging pattern's number and the service name (SHA-1, hex) under the
    configured service directory, as imu-bus computes it (imu_bus::shm owner.rs)."""
    cfg = iox2.config.global_config().global_cfg
    digest = hashlib.sha1(f"{pattern}{service}".encode()).hexdigest()
    path = os.path.join(
        cfg.service_dir.to_string(),
        cfg.prefix.to_string() + digest + cfg.service.static_config_storage_suffix.to_string(),
    )
    try:
        owner = os.stat(path).st_uid
    except FileNotFoundError:
        raise SystemExit(f"imu_subscriber: {service} has no static config at {path}")
    except PermissionError:
        owner = os.stat(os.path.dirname(path)).st_uid
    if owner not in trusted:
        names = ", ".join(user_name(u) for u in sorted(trusted))
        raise SystemExit(
            f"imu_subscriber: {service} was created by {user_name(owner)}, which is not a "
            f"trusted imud publisher (trusted: {names}); refusing its samples"
        )


# The readers' socket packet header (imu_bus::readers): magic, version, stream, reserved, dropped.
HEADER = struct.Struct("<4sHBBQ")
STREAM_CODES = {1: ("raw", RawSample), 2: ("corrected", CorrectedSample)}


def read_socket(args, trusted: set) -> int:
    """Prints from imud's readers' socket until --count samples were printed (or forever)."""
    deadline = time.monotonic() + args.timeout
    while True:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            sock.connect(args.socket)
            break
        except (FileNotFoundError, ConnectionRefusedError):
            sock.close()
            if time.monotonic() >= deadline:
                raise SystemExit(
                    f"imu_subscriber: no imud serves readers at {args.socket}: is imud running "
                    "with [publish] readers-socket (or group) set?"
                )
            time.sleep(0.05)
        except PermissionError:
            raise SystemExit(
                f"imu_subscriber: permission denied connecting to {args.socket}: this user is "
                "not in the socket's group"
            )
    pid, uid, _gid = struct.unpack("3i", sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, 12))
    if uid not in trusted:
        names = ", ".join(user_name(u) for u in sorted(trusted))
        raise SystemExit(
            f"imu_subscriber: the readers' socket {args.socket} is served by pid {pid} "
            f"({user_name(uid)}), which is not a trusted imud publisher (trusted: {names}); "
            "refusing its samples"
        )
    wanted = {"raw", "corrected"} if args.raw else {"corrected"}
    printed = 0
    while args.count == 0 or printed < args.count:
        packet = sock.recv(4096)
        if not packet:
            raise SystemExit(f"imu_subscriber: imud closed the readers' socket {args.socket}")
        if len(packet) < HEADER.size:
            raise SystemExit(f"imu_subscriber: {len(packet)}-byte packet is shorter than a header")
        magic, version, code, _reserved, _dropped = HEADER.unpack_from(packet)
        if magic != b"IMRD" or version != 1:
            raise SystemExit(f"imu_subscriber: not an imud readers' packet (version {version})")
        if code not in STREAM_CODES:
            continue  # status and health: not printed by this example
        stream, payload = STREAM_CODES[code]
        body = packet[HEADER.size :]
        if len(body) != ctypes.sizeof(payload):
            raise SystemExit(f"imu_subscriber: {stream} record of {len(body)} bytes")
        if stream not in wanted:
            continue
        s = payload.from_buffer_copy(body)
        if args.format == "jsonl":
            print(json.dumps({"stream": stream, **to_dict(s)}))
        else:
            print(as_text(stream, s))
        sys.stdout.flush()
        printed += 1
    return 0


def main() -> int:
    """Subscribes and prints until --count samples were printed (or forever)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--name", default="default", help="imud instance name")
    parser.add_argument("--raw", action="store_true", help="also print raw samples")
    parser.add_argument("--count", type=int, default=0, help="exit after N samples (0: never)")
    parser.add_argument("--format", choices=["text", "jsonl"], default="text")
    parser.add_argument(
        "--timeout", type=float, default=10.0, help="seconds to wait for the daemon"
    )
    parser.add_argument(
        "--publisher-user",
        action="append",
        default=[],
        help="a user (name or uid) whose imud to trust; repeatable (default: root, own, imud)",
    )
    parser.add_argument(
        "--socket",
        metavar="PATH",
        help="read imud's readers' socket at PATH instead of shared memory",
    )
    args = parser.parse_args()
    trusted = trusted_uids(args.publisher_user)
    if args.socket:
        return read_socket(args, trusted)
    if iox2 is None:
        raise SystemExit(
            "imu_subscriber: the iceoryx2 package is missing (pip install -r "
            "requirements-dev.txt), or use --socket"
        )

    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = (
        iox2.NodeBuilder.new()
        .signal_handling_mode(iox2.SignalHandlingMode.Disabled)  # keep Ctrl-C for Python
        .create(iox2.ServiceType.Ipc)
    )
    deadline = time.monotonic() + args.timeout

    streams = [("corrected", CorrectedSample)]
    if args.raw:
        streams.insert(0, ("raw", RawSample))  # the daemon publishes raw before corrected
    subscribers = []
    for stream, payload in streams:
        service = f"imud/{args.name}/{stream}"
        factory = open_with_retry(
            lambda: node.service_builder(iox2.ServiceName.new(service))
            .publish_subscribe(payload)
            .open(),
            service,
            args.name,
            deadline,
        )
        check_creator(service, 0, trusted)  # 0: iceoryx2's publish-subscribe pattern
        subscribers.append((stream, factory, factory.subscriber_builder().create()))
    event_service = f"imud/{args.name}/event"
    event = open_with_retry(
        lambda: node.service_builder(iox2.ServiceName.new(event_service)).event().open(),
        event_service,
        args.name,
        deadline,
    )
    check_creator(event_service, 1, trusted)  # 1: iceoryx2's event pattern
    listener = event.listener_builder().create()

    printed = 0
    while args.count == 0 or printed < args.count:
        for stream, _factory, subscriber in subscribers:
            while args.count == 0 or printed < args.count:
                sample = subscriber.receive()
                if sample is None:
                    break
                s = sample.payload().contents
                if args.format == "jsonl":
                    line = json.dumps({"stream": stream, **to_dict(s)})
                else:
                    line = as_text(stream, s)
                del sample  # return the shared-memory slot to the daemon promptly
                print(line)
                printed += 1
        sys.stdout.flush()
        if args.count and printed >= args.count:
            break
        # Sleep until the daemon announces new samples (no polling); the timeout only bounds
        # how late Ctrl-C is noticed.
        try:
            listener.timed_wait(iox2.Duration.from_millis(500))
        except iox2.ListenerWaitError as e:
            # A signal interrupted the wait; Python raises KeyboardInterrupt for SIGINT next.
            if not e.args or e.args[0] != "InterruptSignal":
                raise
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        sys.exit(130)
    except BrokenPipeError:
        # `| head` closed the pipe: not an error. Point stdout at /dev/null so the
        # interpreter's final flush does not complain again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(0)
