#!/usr/bin/env python3
"""A MIP inertial unit on a real pseudo-terminal that misbehaves on purpose (test device for imud).

Independent of imu-sim and of imud's codec: its own packet framing and Fletcher-16 checksum,
written from the protocol facts (sync 0x75 0x65, descriptor set, payload length, fields of
length/descriptor/data, big-endian, checksum = the two running byte sums, sum1 first; a command's
reply is a packet of the command's set whose first field is 0xF1 = [command, ack code], followed
by a response field). It answers, like a 3DM-GX5-25:
  base set 0x01:  0x01 ping, 0x02 set to idle, 0x03 device info (reply 0x81), 0x06 resume
  3DM set 0x0C:   0x06 IMU base rate (0x83), 0x08 IMU message format (0x80),
                  0x0E base rate of a set (0x8E), 0x0F message format of a set (0x8F),
                  0x11 data stream on/off (0x85)
and streams IMU data set 0x80 packets with the configured fields: 0x04 scaled accel (g), 0x05
scaled gyro (rad/s), 0x06 scaled mag (gauss), 0x0E internal timestamp (u32 at 62.5 kHz), 0x14
temperature (min, max, mean in deg C), 0xD5 reference time (u64 ns since power-on).

The values of frame k are a fixed pattern (see `values`), so a test can check every sample.
Options:
  --rate-hz R            data rate the unit is set to at power-on (base rate 1000 Hz)
  --no-reference-time    the unit has no 0xD5 (as a 3DM-GX3): a format asking for it is nacked
  --no-temperature       ... no 0x14
  --no-mag               ... no 0x06 (an IMU without magnetometer)
  --generic-only         legacy 3DM 0x06 and 0x08 are unknown commands (as the 7-series)
  --streaming            powers up streaming (it must be set to idle before it is configured)
  --delay-reply N:S      answer the N-th command (1-based) S seconds late (busy meanwhile)
  --corrupt-replies P    flip each byte of command replies with probability P
  --drop K,K,...         never send data frames with these indices (the clock runs on)
  --stall AT:S           AT seconds into streaming, send nothing for S seconds
  --drift-ppm D          the unit's oscillator runs D ppm fast
On SIGTERM it writes a JSON report of the last streaming session (frames sent, first/last
index, dropped between them), the format in force and the commands answered to --report.
"""

import argparse
import random
import struct
import sys
import time

from pty_device import serve

BASE_RATE_HZ = 1000
TICK_HZ = 62500
SUPPORTED = [0x04, 0x05, 0x06, 0x0E, 0x14, 0xD5]


def fletcher(data: bytes) -> bytes:
    s1 = s2 = 0
    for b in data:
        s1 = (s1 + b) & 0xFF
        s2 = (s2 + s1) & 0xFF
    return bytes([s1, s2])


def packet(desc_set: int, fields) -> bytes:
    payload = b"".join(bytes([len(data) + 2, desc]) + data for desc, data in fields)
    head = bytes([0x75, 0x65, desc_set, len(payload)])
    return head + payload + fletcher(head + payload)


def parse_packets(buf: bytearray):
    """Complete packets at the head of buf (garbage before a sync is dropped)."""
    out = []
    while True:
        i = buf.find(b"\x75\x65")
        if i < 0:
            del buf[: max(0, len(buf) - 1)]
            return out
        del buf[:i]
        if len(buf) < 4 or len(buf) < 6 + buf[3]:
            return out
        n = 6 + buf[3]
        pkt = bytes(buf[:n])
        if fletcher(pkt[:-2]) != pkt[-2:]:
            del buf[:1]
            continue
        del buf[:n]
        fields, p = [], pkt[4:-2]
        while len(p) >= 2 and p[0] >= 2:
            fields.append((p[1], p[2 : p[0]]))
            p = p[p[0] :]
        out.append((pkt[2], fields))


def values(k: int):
    """Accel (g), gyro (rad/s), mag (gauss), temperature (deg C) of frame k."""
    accel = [0.001 * (k % 7), -0.002 * (k % 5), -1.0 + 1e-4 * (k % 3)]
    gyro = [1e-3 * ((k % 11) - 5), 2e-3, -5e-4 * (k % 4)]
    mag = [0.21, -0.05 + 0.001 * (k % 2), 0.43]
    return accel, gyro, mag, 24.5 + 0.01 * (k % 10)


class Device:
    def __init__(self, args):
        self.args = args
        self.rng = random.Random(args.seed)
        self.power_on = time.monotonic() - args.power_on_s
        self.scale = 1.0 + args.drift_ppm * 1e-6
        dec = BASE_RATE_HZ // int(args.rate_hz)
        self.format = [(d, dec) for d in (0x04, 0x05, 0x06, 0xD5) if self.supports(d)]
        self.idle = not args.streaming
        self.stream_enabled = True
        self.start = None  # (monotonic, next frame index)
        self.commands = 0
        self.answered = []
        self.out = bytearray()
        self.inbuf = bytearray()
        self.hold_until = 0.0
        self.stalled_once = False
        self.sent, self.dropped = [], []
        if args.streaming:
            self.start_streaming()

    def supports(self, d: int) -> bool:
        a = self.args
        return d in SUPPORTED and not (
            (d == 0xD5 and a.no_reference_time)
            or (d == 0x14 and a.no_temperature)
            or (d == 0x06 and a.no_mag)
        )

    def start_streaming(self):
        # The report covers the last streaming session (the one a host configured).
        self.start = (time.monotonic(), 0)
        self.sent, self.dropped = [], []

    def corrupt(self, data: bytes) -> bytes:
        p = self.args.corrupt_replies
        out = bytearray(data)
        for i in range(len(out)):
            if p > 0 and self.rng.random() < p:
                out[i] ^= self.rng.randint(1, 255)
        return bytes(out)

    def reply(self, desc_set, cmd, code, response=None):
        fields = [(0xF1, bytes([cmd, code]))]
        if response is not None and code == 0:
            fields.append(response)
        data = packet(desc_set, fields)
        self.commands += 1
        self.answered.append([desc_set, cmd, code])
        if self.args.delay_reply and self.commands == self.args.delay_reply[0]:
            self.hold_until = max(self.hold_until, time.monotonic() + self.args.delay_reply[1])
        self.out += self.corrupt(data)

    def format_bytes(self):
        return bytes([len(self.format)]) + b"".join(struct.pack(">BH", d, r) for d, r in self.format)

    def message_format(self, desc_set, cmd, data, generic):
        if generic:
            if len(data) < 2 or data[1] != 0x80:
                return self.reply(desc_set, cmd, 3)
            selector, rest = data[0], data[2:]
        else:
            selector, rest = data[0], data[1:]
        if selector == 1:
            n = rest[0] if rest else 0
            fields = [struct.unpack(">BH", rest[1 + 3 * i : 4 + 3 * i]) for i in range(n)]
            if len(rest) != 1 + 3 * n or any(not self.supports(d) or r < 1 for d, r in fields):
                return self.reply(desc_set, cmd, 3)
            self.format = fields
            return self.reply(desc_set, cmd, 0)
        if selector == 2:
            body = (bytes([0x80]) if generic else b"") + self.format_bytes()
            return self.reply(desc_set, cmd, 0, (0x8F if generic else 0x80, body))
        return self.reply(desc_set, cmd, 0)

    def command(self, desc_set, cmd, data):
        if desc_set == 0x01 and cmd in (0x01, 0x02, 0x06):
            if cmd == 0x02:
                self.idle, self.start = True, None
            elif cmd == 0x06:
                self.idle = False
                self.start_streaming()
            return self.reply(desc_set, cmd, 0)
        if desc_set == 0x01 and cmd == 0x03:
            info = struct.pack(">H", 1141) + b"".join(
                s.ljust(16).encode() for s in ["3DM-GX5-25", "6251-4220", "6251.99", "lot-7", "8g,300dps"]
            )
            return self.reply(desc_set, cmd, 0, (0x81, info))
        legacy = not self.args.generic_only
        if desc_set == 0x0C and cmd == 0x06 and legacy:
            return self.reply(desc_set, cmd, 0, (0x83, struct.pack(">H", BASE_RATE_HZ)))
        if desc_set == 0x0C and cmd == 0x0E:
            if data[:1] != b"\x80":
                return self.reply(desc_set, cmd, 3)
            return self.reply(desc_set, cmd, 0, (0x8E, b"\x80" + struct.pack(">H", BASE_RATE_HZ)))
        if desc_set == 0x0C and cmd == 0x08 and legacy:
            return self.message_format(desc_set, cmd, data, generic=False)
        if desc_set == 0x0C and cmd == 0x0F:
            return self.message_format(desc_set, cmd, data, generic=True)
        if desc_set == 0x0C and cmd == 0x11:
            if data[:1] == b"\x01" and data[1:2] == b"\x80":
                self.stream_enabled = data[2:3] == b"\x01"
            return self.reply(desc_set, cmd, 0)
        return self.reply(desc_set, cmd, 1)

    def handle_input(self):
        for desc_set, fields in parse_packets(self.inbuf):
            for cmd, data in fields:
                self.command(desc_set, cmd, data)

    def data_packet(self, k: int, device_s: float) -> bytes:
        accel, gyro, mag, temp = values(k)
        by = {
            0x04: struct.pack(">3f", *accel),
            0x05: struct.pack(">3f", *gyro),
            0x06: struct.pack(">3f", *mag),
            0x0E: struct.pack(">I", int(device_s * TICK_HZ) & 0xFFFFFFFF),
            0x14: struct.pack(">3f", temp - 0.1, temp + 0.1, temp),
            0xD5: struct.pack(">Q", int(device_s * 1e9)),
        }
        return packet(0x80, [(d, by[d]) for d, _ in self.format])

    def stream(self):
        if self.start is None or self.idle or not self.stream_enabled or not self.format:
            return
        start, k = self.start
        period = self.format[0][1] / BASE_RATE_HZ
        now = time.monotonic()
        # The unit's oscillator is `scale` fast: it sends frame k at k * period of its own time.
        while start + k * period / self.scale <= now:
            device_s = (start - self.power_on) * self.scale + k * period
            if k in self.args.drop:
                self.dropped.append(k)
            else:
                self.out += self.data_packet(k, device_s)
                self.sent.append(k)
            k += 1
        self.start = (start, k)
        if self.args.stall and not self.stalled_once and now - start >= self.args.stall[0]:
            self.stalled_once = True
            self.hold_until = max(self.hold_until, now + self.args.stall[1])

    def report(self):
        first, last = (self.sent[0], self.sent[-1]) if self.sent else (0, -1)
        return {
            "frames_sent": len(self.sent),
            "first": first,
            "last": last,
            "dropped_between": len([k for k in self.dropped if first < k < last]),
            "format": self.format,
            "answered": self.answered,
        }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--report", required=True)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--power-on-s", type=float, default=30.0)
    ap.add_argument("--no-reference-time", action="store_true")
    ap.add_argument("--no-temperature", action="store_true")
    ap.add_argument("--no-mag", action="store_true")
    ap.add_argument("--generic-only", action="store_true")
    ap.add_argument("--streaming", action="store_true")
    ap.add_argument("--delay-reply", type=lambda s: (int(s.split(":")[0]), float(s.split(":")[1])))
    ap.add_argument("--corrupt-replies", type=float, default=0.0)
    ap.add_argument("--drop", type=lambda s: {int(x) for x in s.split(",") if x}, default=set())
    ap.add_argument("--stall", type=lambda s: (float(s.split(":")[0]), float(s.split(":")[1])))
    ap.add_argument("--drift-ppm", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    serve(Device(args), args.link, args.report, poll_s=0.001)


if __name__ == "__main__":
    sys.exit(main())
