#!/usr/bin/env python3
"""Writes synthetic_right_hand.json: a SYNTHETIC 162-taxel hand template (not the real glove layout).

Geometry: a palm with five straight fingers, each a capsule (rectangle with a round cap) given by its base
centre, direction, length and width, in grid units with y pointing down (fingers up, thumb to the left).
Per finger: 6 tip taxels (distal segment), 6 seg taxels (middle/proximal segments, the stabilisation group),
2 base taxels ("other"; 4 on the thumb); the palm holds a 9 x 10 grid. 5*(6+6+2) + 2 + 90 = 162.
Standard library only; run it from this folder: python3 make_synthetic_template.py
"""
import json
import math

FINGERS = [  # name, base centre, direction (degrees from straight up, + = towards the little finger), length, width
    ("thumb", (10.0, 74.0), -36.87, 32.0, 11.0),
    ("index", (20.0, 47.0), -4.0, 36.0, 9.0),
    ("middle", (30.0, 45.0), 0.0, 40.0, 9.5),
    ("ring", (40.0, 47.0), 4.0, 37.0, 9.0),
    ("little", (49.5, 51.0), 10.0, 29.0, 8.0),
]
TIP_ROWS = (0.92, 0.82, 0.72)   # fractions of the length from the base
SEG_ROWS = (0.58, 0.45, 0.32)
BASE_ROWS = {"thumb": (0.14, 0.02)}
DEFAULT_BASE_ROWS = (0.15,)
WRIST_Y = 100.0


def frame(base, angle_deg):
    a = math.radians(angle_deg)
    d = (math.sin(a), -math.cos(a))   # towards the tip (y down)
    n = (-d[1], d[0])                  # to the right of the finger when looking at the tip
    return d, n


def at(base, d, n, u, v):
    return (base[0] + u * d[0] + v * n[0], base[1] + u * d[1] + v * n[1])


def finger_outline(base, angle, length, width, arc_points=9):
    """Right side base -> right side top -> cap -> left side top -> left side base, walking counter-clockwise
    on screen for an upright finger seen from the palm (the order the hand outline needs)."""
    d, n = frame(base, angle)
    r = width / 2
    cap = length - r
    pts = [at(base, d, n, 0, r), at(base, d, n, cap, r)]
    for k in range(1, arc_points):
        t = math.pi * k / arc_points
        pts.append(at(base, d, n, cap + r * math.sin(t), r * math.cos(t)))
    pts += [at(base, d, n, cap, -r), at(base, d, n, 0, -r)]
    return pts


def finger_sensors(name, base, angle, length, width):
    d, n = frame(base, angle)
    v = 0.22 * width
    out = []
    for region, rows in ((f"tip_{name}", TIP_ROWS), (f"seg_{name}", SEG_ROWS),
                         ("other", BASE_ROWS.get(name, DEFAULT_BASE_ROWS))):
        for f in rows:
            for side in (-v, v):
                out.append((at(base, d, n, f * length, side), region))
    return out


def hand_outline():
    # Walk: wrist right -> palm right edge -> little, ring, middle, index (right to left) -> palm left edge ->
    # thumb -> wrist left. Fingers are traversed right side first, i.e. clockwise on screen with y down.
    pts = [(50.0, WRIST_Y), (55.0, 90.0), (55.0, 62.0)]
    for name, base, angle, length, width in reversed(FINGERS[1:]):
        pts += finger_outline(base, angle, length, width)
    pts += [(15.0, 58.0)]
    name, base, angle, length, width = FINGERS[0]
    pts += finger_outline(base, angle, length, width)
    pts += [(15.0, WRIST_Y)]
    return pts


def palm_sensors():
    xs = [19.0 + 4.0 * c for c in range(9)]
    ys = [55.0 + 4.6 * r for r in range(10)]
    return [((x, y), "palm") for y in ys for x in xs]


def inside(poly, x, y):
    # Even-odd rule exactly as pressure.md section 4.3.
    c = False
    for k in range(len(poly)):
        ax, ay = poly[k]
        bx, by = poly[(k + 1) % len(poly)]
        if (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay):
            c = not c
    return c


def main():
    sensors = []
    for f in FINGERS:
        sensors += finger_sensors(*f)
    sensors += palm_sensors()
    outline = hand_outline()
    # Shift so that every coordinate is positive (cosmetic; grid units are arbitrary).
    dx = 1.0 - min(p[0] for p in outline)
    dy = 1.0 - min(p[1] for p in outline)
    outline = [(x + dx, y + dy) for x, y in outline]
    sensors = [((x + dx, y + dy), r) for (x, y), r in sensors]
    assert len(sensors) == 162, len(sensors)
    for (x, y), r in sensors:
        assert inside(outline, x, y), (x, y, r)
    doc = {
        "format": "egopd-hand-template/1",
        "name": "synthetic-right-hand-v0",
        "synthetic": True,
        "description": "SYNTHETIC layout for testing and demos; NOT the EgoTactile glove's real taxel layout. "
                       "Supply the real glove layout in this format for meaningful CoP errors.",
        "coordinate_system": {"units": "grid", "y_axis": "down"},
        "sensors": [{"id": i, "x": round(x, 3), "y": round(y, 3), "region": r}
                    for i, ((x, y), r) in enumerate(sensors)],
        "outline": [[round(x, 3), round(y, 3)] for x, y in outline],
    }
    with open("synthetic_right_hand.json", "w") as f:
        # One sensor / vertex per line keeps diffs readable.
        f.write("{\n")
        keys = [k for k in doc if k not in ("sensors", "outline")]
        for k in keys:
            f.write(f"  {json.dumps(k)}: {json.dumps(doc[k])},\n")
        f.write('  "sensors": [\n')
        f.write(",\n".join("    " + json.dumps(s) for s in doc["sensors"]))
        f.write("\n  ],\n")
        f.write('  "outline": [\n')
        f.write(",\n".join("    " + json.dumps(p) for p in doc["outline"]))
        f.write("\n  ]\n}\n")


if __name__ == "__main__":
    main()
