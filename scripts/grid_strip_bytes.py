#!/usr/bin/env python3
"""Bytes per triangle of a grid file's strip data, by part of the block (vertex_encoding 3 or 5,
docs/FORMAT.md "strip_data"), and what the strip-layout levers measured for format 4 would
leave of it, computed from the same blocks:

    scripts/grid_strip_bytes.py MODEL.rdm
"""
import struct
import sys
from collections import Counter

data = open(sys.argv[1], "rb").read()
encoding, leaf = struct.unpack_from("<II", data, 20)
triangles, strips = struct.unpack_from("<QQ", data, 32)
sections = [struct.unpack_from("<IIQQQ", data, 104 + 32 * i) for i in range(3)]
grid_bits = struct.unpack_from("<I", data, 208)[0]
if encoding not in (3, 5):
    sys.exit(f"vertex encoding {encoding}: not a packed grid file")
records, strip_data = sections[1][2], sections[2][2]


def shift(width, slack):
    return max(width - slack, 0) if slack else 0


def axis_words(head):
    """(anchor, width) per axis and the words' bits, as the file's encoding stores them."""
    words, bit = [], 0
    for _ in range(3):
        if encoding == 3:
            word = head >> bit
            words.append((word & ((1 << grid_bits) - 1), (word >> grid_bits) & 31))
            bit += grid_bits + 5
        else:
            width = (head >> bit) & 31
            t = shift(width, 3)
            anchor = ((head >> (bit + 5)) & ((1 << (grid_bits - t)) - 1)) << t
            words.append((anchor, width))
            bit += 5 + grid_bits - t
    return words, bit


def aligned_word_bits(low, high, slack):
    """Bits of an axis word and one vertex's offset with anchors aligned at `slack`."""
    width = (high - low).bit_length()
    while True:
        t = shift(width, slack)
        anchor = min(low >> t << t, (1 << grid_bits) - (1 << width))
        if high - anchor < 1 << width:
            return 5 + grid_bits - t, width
        width += 1


def pad4(n):
    return n + (-n) % 4


total = Counter()
for s in range(strips):
    word, vertices, references = struct.unpack_from("<IHH", data, records + 8 * s)
    start = strip_data + 4 * word
    head = int.from_bytes(data[start:start + 16], "little")
    words, header_bits = axis_words(head)
    stride = sum(w for _, w in words)
    vertex_bytes = (header_bits + vertices * stride + 7) // 8
    stream = int.from_bytes(data[start:start + vertex_bytes + 8], "little")
    points = []
    for i in range(vertices):
        bit = header_bits + i * stride
        point = []
        for anchor, width in words:
            point.append(anchor + ((stream >> bit) & ((1 << width) - 1)))
            bit += width
        points.append(point)
    low = [min(p[a] for p in points) for a in range(3)]
    high = [max(p[a] for p in points) for a in range(3)]
    windows = references - 2
    axes = (max(-(-windows // leaf) - 1, 0) + 3) // 4
    reference_bits = max(1, (vertices - 1).bit_length())
    reference_bytes = max(3, -(-references * reference_bits // 8))
    at = start + vertex_bytes + axes
    packed = int.from_bytes(data[at:at + reference_bytes], "little")
    mask = (1 << reference_bits) - 1
    strip = [(packed >> (k * reference_bits)) & mask for k in range(references)]
    blocks = -(-windows // 8)
    boxes = 3 + 3 * blocks if windows > 8 and encoding == 3 else 0
    stored = vertex_bytes + axes + reference_bytes + boxes
    total["axis words"] += header_bits / 8
    total["offsets"] += vertex_bytes - header_bits / 8
    total["split axes"] += axes
    total["references"] += reference_bytes
    total["block boxes"] += boxes
    total["padding"] += pad4(stored) - stored
    rest = axes + reference_bytes
    full_words = [aligned_word_bits(low[a], high[a], 0) for a in range(3)]
    full = (sum(b for b, _ in full_words) + vertices * sum(w for _, w in full_words) + 7) // 8
    box_area = 3 + 3 * blocks if windows > 8 else 0
    total["lever: with boxes, full anchors (encoding 3)"] += pad4(full + rest + box_area)
    three_bit = 3 + -(-18 * blocks // 8) if windows > 8 else 0
    total["lever: boxes in 3-bit codes"] += pad4(full + rest + three_bit)
    sixteen = 3 + 3 * -(-windows // 16) if windows > 16 else 0
    total["lever: a box per 16 windows"] += pad4(full + rest + sixteen)
    total["lever: no boxes, full anchors"] += pad4(full + rest)
    # A flag per reference: set for the first stored vertex not yet referenced, else an index.
    seen, next_new, indexed = set(), 0, 0
    for reference in strip:
        while next_new in seen:
            next_new += 1
        indexed += reference != next_new
        seen.add(reference)
    flagged = max(3, -(-(references + indexed * reference_bits) // 8))
    total["lever: no boxes, full anchors, flagged references"] += pad4(full + axes + flagged)
    # Zigzag deltas between consecutive stored vertices, at the widest per axis.
    delta_widths = 0
    for a in range(3):
        deltas = [q[a] - p[a] for p, q in zip(points, points[1:])]
        delta_widths += max([2 * d if d >= 0 else -2 * d - 1 for d in deltas] + [0]).bit_length()
    delta = (3 * (grid_bits + 5) + (vertices - 1) * delta_widths + 7) // 8
    total["lever: no boxes, delta-coded vertices"] += pad4(delta + rest)
    for slack in range(1, 6):
        aligned = [aligned_word_bits(low[a], high[a], slack) for a in range(3)]
        bits = sum(b for b, _ in aligned) + vertices * sum(w for _, w in aligned)
        total[f"lever: no boxes, anchors aligned, slack {slack}"] += pad4((bits + 7) // 8 + rest)

print(f"{sys.argv[1]}: vertex encoding {encoding}, {triangles} triangles, {strips} strips")
print(f"strip_data {sections[2][3] / triangles:.3f} B/tri, strip_records {8 * strips / triangles:.3f}")
for part, value in total.items():
    print(f"  {part:48} {value / triangles:.3f} B/tri")
