#!/usr/bin/env python3
"""Write seed inputs for the fuzz targets into fuzz/corpus/<target>/ (gitignored).

Frames are built here independently of the Rust code (CRC-16/CCITT-FALSE via
binascii.crc_hqx with init 0xFFFF). Usage: python3 fuzz/make_seeds.py
"""
import binascii
import os
import random
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def frame(seq, counter, temp=2500, status=7):
    body = b"\xa5\x5a" + struct.pack("<HIhHH", seq & 0xFFFF, counter & 0xFFFFFFFF, temp, status, 0)
    return body + struct.pack("<H", binascii.crc_hqx(body, 0xFFFF))


def stream(rng, n, seq, counter):
    out = bytearray()
    for _ in range(n):
        out += frame(seq, counter, rng.randint(-500, 500), rng.choice([7, 7, 7, 5, 3]))
        seq += 1 if rng.random() > 0.05 else rng.randint(0, 6)
        counter += rng.randint(-40, 40)
    return out


def corrupt(rng, data):
    data = bytearray(data)
    for _ in range(rng.randint(0, 4)):
        i = rng.randrange(len(data))
        data[i] ^= 1 << rng.randrange(8)
    for _ in range(rng.randint(0, 3)):
        i = rng.randrange(len(data))
        data[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 20)))
    return bytes(data)


def main():
    rng = random.Random(20240605)
    d = os.path.join(HERE, "corpus", "decode")
    os.makedirs(d, exist_ok=True)
    for k in range(24):
        s = stream(rng, rng.randint(2, 60), rng.choice([0, 65530, rng.randrange(65536)]),
                   rng.choice([0, 0xFFFFFFF0, rng.randrange(2**32)]))
        if k % 2:
            s = corrupt(rng, s)
        knob = bytes([rng.randrange(256)])
        with open(os.path.join(d, f"seed_{k:02}.bin"), "wb") as f:
            f.write(knob + s)
    d = os.path.join(HERE, "corpus", "ledger")
    os.makedirs(d, exist_ok=True)
    for k in range(16):
        head = struct.pack("<HI", rng.choice([65500, rng.randrange(65536)]), rng.choice([0xFFFFFF00, rng.randrange(2**32)]))
        recs = b"".join(struct.pack("<hBB", rng.randint(-50, 50), rng.randrange(256), rng.randrange(256))
                        for _ in range(rng.randint(1, 80)))
        with open(os.path.join(d, f"seed_{k:02}.bin"), "wb") as f:
            f.write(head + recs)


if __name__ == "__main__":
    main()
