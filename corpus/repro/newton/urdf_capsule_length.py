"""Newton's URDF importer ignores a capsule's `length` attribute.

A capsule in URDF is written `<capsule radius="R" length="L"/>` (the attribute name of URDF's cylinder, and what
Drake, PyBullet and Isaac's URDF importer read; Unitree's H1-2 URDF uses it). Expectation: the imported capsule
has radius R and half height L/2. newton 1.8.0 (`pip install newton==1.8.0`, CPU is enough): the importer reads
an attribute `height` instead, finds none and silently falls back to 1 m, so the capsule gets half height 0.5
whatever L says, with no warning (newton/_src/utils/import_urdf.py, `capsule.get("height") or "1"`; the
cylinder branch next to it reads `length`). A robot whose limbs are capsules gets 1 m long colliders.

Prints the imported size and exits 1 when the half height is not L/2 (0 when Newton honours `length`).
"""
import sys
import warnings

import newton
import warp as wp

wp.config.quiet = True
RADIUS, LENGTH = 0.05, 0.2
URDF = f"""<?xml version="1.0"?>
<robot name="capsule_test">
  <link name="rod">
    <inertial><mass value="1.0"/><inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><capsule radius="{RADIUS}" length="{LENGTH}"/></geometry></collision>
  </link>
</robot>
"""

builder = newton.ModelBuilder()
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    builder.add_urdf(URDF, floating=True)
model = builder.finalize(device="cpu")
capsules = [i for i, t in enumerate(model.shape_type.numpy()) if t == int(newton.GeoType.CAPSULE)]
if len(capsules) != 1:
    print(f"newton {newton.__version__}: expected one capsule shape, found {len(capsules)}")
    sys.exit(1)
radius, half_height = (float(x) for x in model.shape_scale.numpy()[capsules[0]][:2])
print(f"newton {newton.__version__}: URDF <capsule radius={RADIUS} length={LENGTH}/>")
print(f"  expected radius {RADIUS}, half height {LENGTH / 2}")
print(f"  imported radius {radius:.6g}, half height {half_height:.6g}")
print(f"  warnings during import: {[str(w.message) for w in caught] or 'none'}")
ok = abs(radius - RADIUS) < 1e-6 and abs(half_height - LENGTH / 2) < 1e-6
print("  OK: length honoured" if ok else "  WRONG: capsule length ignored")
sys.exit(0 if ok else 1)
