#!/usr/bin/env python3
"""bench/scenes/make-bunnies.py: writes cornell-bunnies-1m.json and
cornell-bunnies-1m-hidden.json beside itself.

Issue 16's generated big scene: the empty Cornell box (CornellBox-Empty-CO, its
light in the ceiling) with 15 Stanford bunnies standing on its floor in a 5 x 3
grid, 15 x 69,451 = 1,041,765 triangles and about 1.04 million in all. Each
bunny is its own mesh entry (the scene model has no instancing: the loader
expands them). Paths point into ../shared, nothing is copied. Run it again to
regenerate the descriptions.

The hidden variant stands the same bunnies 2 units further back, behind the box's
back wall (z = -1.04): the camera sees the empty room, and no gather from it
reaches them (the box is open only towards the camera). Start-up should not pay
for them (issue 16, "start-up bounded by what is seen").
"""
import json
import os

SHARED = "../../../shared/scenes"
S = 2.2                                   # bunny scale: about 0.34 wide, 0.34 tall
BUNNY_MIN_Y = 0.032987                    # the bunny's lowest y in its file
XS = [-0.72, -0.36, 0.0, 0.36, 0.72]
ZS = [-0.62, -0.17, 0.28]
meshes = [{"file": SHARED + "/cornell-box/CornellBox-Empty-CO.obj"}]
for i, z in enumerate(ZS):
    for x in XS:
        meshes.append({"file": SHARED + "/stanford-bunny/stanford-bunny.obj",
                       "transform": [S, 0, 0, x, 0, S, 0, -S * BUNNY_MIN_Y + 0.001, 0, 0, S, z, 0, 0, 0, 1],
                       "material": "bunny%d" % i})
materials = {"bunny0": {"kd": [0.75, 0.7, 0.6]}, "bunny1": {"kd": [0.6, 0.65, 0.75]},
             "bunny2": {"kd": [0.7, 0.55, 0.5]}}
HIDDEN_DZ = -2.0                          # behind the back wall
for name, dz in (("cornell-bunnies-1m.json", 0.0), ("cornell-bunnies-1m-hidden.json", HIDDEN_DZ)):
    moved = [dict(m) for m in meshes]
    for m in moved[1:]:
        m["transform"] = list(m["transform"])
        m["transform"][11] += dz
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), name)
    with open(out, "w") as f:
        json.dump({"meshes": moved, "materials": materials}, f, indent=1)
        f.write("\n")
    print("wrote", out)
