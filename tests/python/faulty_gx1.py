#!/usr/bin/env python3
"""A 3DM-GX1 on a real pseudo-terminal that misbehaves on purpose (test device for imud).

Independent of imu-sim: its own framing (checksum as in the protocol notes), its own clock.
It answers 0x10 (continuous mode), 0x28 (EEPROM read: the three GainScales), 0xF0, 0xF1, 0x07
and 0x01, streams 0x01 raw-bits frames in continuous mode, and can
  --delay-eeprom N:S     answer the N-th EEPROM read (1-based) S seconds late (in order: it is
                         busy meanwhile, as a real device would be)
  --duplicate-eeprom N   answer the N-th EEPROM read twice
  --corrupt-replies P    replace each byte of command replies with probability P
  --drop K,K,...         never send data frames with these indices (the clock runs on)
  --stall AT:S           AT seconds into streaming, send nothing for S seconds (the frames
                         queue up and go out at once afterwards)
The device's tick counter is the truth: frame k of a stream is sampled at k / rate-hz seconds of
device time. On SIGTERM it writes a JSON report (frames sent, dropped between the first and last
sent, EEPROM reads answered) to --report and exits.
"""

import argparse
import random
import struct
import sys
import time

from pty_device import serve

GAIN_ADDRS = {230: "accel", 130: "gyro", 232: "mag"}


def checksum(frame: bytes) -> int:
    total = frame[0]
    for i in range(1, len(frame) - 1, 2):
        total += (frame[i] << 8) | frame[i + 1]
    return total & 0xFFFF


def reply(code: int, words, prefix: bytes = b"") -> bytes:
    body = bytes([code]) + prefix + b"".join(struct.pack(">H", w & 0xFFFF) for w in words)
    return body + struct.pack(">H", checksum(body + b"\0\0"))


def raw_frame(k: int, ticks: int) -> bytes:
    w = lambda i: 32768 + (k * 7 + i * 13) % 50
    mag = [w(0), w(1), w(2)]
    accel = [w(3), w(4), 32768 + 4681]
    rate = [w(6), w(7), w(8)]
    return reply(0x01, mag + accel + rate + [ticks])


class Device:
    def __init__(self, args):
        self.args = args
        self.rng = random.Random(args.seed)
        self.power_on = time.monotonic() - args.power_on_s
        self.gains = dict(zip(["accel", "gyro", "mag"], args.gains))
        self.eeprom_reads = 0
        self.streaming = None  # (start monotonic, next frame index)
        self.sent = []
        self.dropped = []
        self.out = bytearray()
        self.hold_until = 0.0
        self.stalled_once = False
        self.inbuf = bytearray()

    def ticks(self, device_s: float) -> int:
        return int(device_s / self.args.tick_s) % 65536

    def now_ticks(self) -> int:
        return self.ticks(time.monotonic() - self.power_on)

    def corrupt(self, data: bytes) -> bytes:
        p = self.args.corrupt_replies
        if p <= 0:
            return data
        out = bytearray(data)
        for i in range(len(out)):
            if self.rng.random() < p:
                out[i] ^= self.rng.randint(1, 255)
        return bytes(out)

    def answer(self, data: bytes, delay_s: float = 0.0):
        if delay_s > 0:
            # Busy: nothing else goes out (and later commands wait) until this reply is sent.
            self.hold_until = max(self.hold_until, time.monotonic() + delay_s)
        self.out += self.corrupt(data)

    def command(self) -> bool:
        """Handles one command from the input buffer; False when more bytes are needed."""
        buf = self.inbuf
        code = buf[0]
        need = {0x10: 3, 0x28: 3}.get(code, 1)
        if len(buf) < need:
            return False
        cmd = bytes(buf[:need])
        del buf[:need]
        t = self.now_ticks()
        if code == 0x10:
            if cmd[2] == 0:
                self.streaming = None
            else:
                self.streaming = (time.monotonic(), 1)
            self.answer(reply(0x10, [t], prefix=bytes([0x00, cmd[2]])))
        elif code == 0x28:
            self.eeprom_reads += 1
            addr = (cmd[1] << 8) | cmd[2]
            value = self.gains.get(GAIN_ADDRS.get(addr, ""), 0)
            frame = reply(0x28, [value, t])
            delay = 0.0
            if self.args.delay_eeprom and self.eeprom_reads == self.args.delay_eeprom[0]:
                delay = self.args.delay_eeprom[1]
            self.answer(frame, delay)
            if self.eeprom_reads == self.args.duplicate_eeprom:
                self.answer(frame)
        elif code == 0xF0:
            self.answer(reply(0xF0, [3105]))
        elif code == 0xF1:
            self.answer(reply(0xF1, [4242]))
        elif code == 0x07:
            self.answer(reply(0x07, [int((0.25 + 0.5) / 5 * 65536), t]))
        elif code == 0x01:
            self.answer(raw_frame(0, t))
        # other bytes: ignored, as garbage
        return True

    def handle_input(self):
        while self.inbuf and self.command():
            pass

    def stream(self):
        if self.streaming is None:
            return
        start, k = self.streaming
        period = 1.0 / self.args.rate_hz
        now = time.monotonic()
        while start + k * period <= now:
            device_s = (start - self.power_on) + k * period
            if k in self.args.drop:
                self.dropped.append(k)
            else:
                self.out += raw_frame(k, self.ticks(device_s))
                self.sent.append(k)
            k += 1
        self.streaming = (start, k)
        if self.args.stall and not self.stalled_once and now - start >= self.args.stall[0]:
            self.stalled_once = True
            self.hold_until = max(self.hold_until, now + self.args.stall[1])

    def report(self):
        first, last = (self.sent[0], self.sent[-1]) if self.sent else (0, -1)
        return {
            "frames_sent": len(self.sent),
            "dropped_between": len([k for k in self.dropped if first < k < last]),
            "eeprom_reads": self.eeprom_reads,
            "gains": self.gains,
        }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--link", required=True)
    ap.add_argument("--report", required=True)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--tick-s", type=float, default=6.5536e-3)
    ap.add_argument("--power-on-s", type=float, default=12.0)
    ap.add_argument("--gains", type=lambda s: [int(x) for x in s.split(",")], default=[8500, 8800, 2500])
    ap.add_argument("--delay-eeprom", type=lambda s: (int(s.split(":")[0]), float(s.split(":")[1])))
    ap.add_argument("--duplicate-eeprom", type=int, default=0)
    ap.add_argument("--corrupt-replies", type=float, default=0.0)
    ap.add_argument("--drop", type=lambda s: {int(x) for x in s.split(",") if x}, default=set())
    ap.add_argument("--stall", type=lambda s: (float(s.split(":")[0]), float(s.split(":")[1])))
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    serve(Device(args), args.link, args.report)


if __name__ == "__main__":
    sys.exit(main())
