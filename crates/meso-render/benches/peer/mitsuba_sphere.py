"""The renderer benchmark's scene in Mitsuba 3, as a peer to compare with on the same machine.

`bench_sphere`'s scene (crates/meso-render/benches/common/mod.rs): a unit sphere seen from
(0, 0, 3.2) with a 40° field of view, 1024² pixels, 1 spp, four point lights of intensity 10 at
the same places, one Beckmann or GGX lobe of α = 0.2 on a conductor (`roughconductor`), the
`direct` integrator with 4 emitter samples and no BSDF samples: four light evaluations per
pixel, each with its shadow ray, as meso's stream path does (Mitsuba picks the light of each
sample at random, meso visits each of the four).

    target/venv/bin/python crates/meso-render/benches/peer/mitsuba_sphere.py [VARIANT] [beckmann|ggx] [FRAMES]

(the venv of crates/meso-py/tests/run.sh has Mitsuba 3). Prints the wall time per frame and the
process CPU time per frame (all threads; meaningful on a loaded machine), after one warm-up frame
that compiles the kernels. Figures: docs/benchmarks.md.
"""
import os
import sys
import time

import drjit as dr
import mitsuba as mi

variant = sys.argv[1] if len(sys.argv) > 1 else "llvm_ad_rgb"
dist = sys.argv[2] if len(sys.argv) > 2 else "beckmann"
frames = int(sys.argv[3]) if len(sys.argv) > 3 else 10
mi.set_variant(variant)


def light(p):
    return {"type": "point", "position": p, "intensity": {"type": "rgb", "value": 10.0}}


scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 0},
    "sensor": {
        "type": "perspective",
        "fov": 40,
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 3.2], target=[0, 0, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 1024, "height": 1024, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": 1},
    },
    "sphere": {"type": "sphere", "bsdf": {"type": "roughconductor", "distribution": dist, "alpha": 0.2}},
    "l1": light([3, 3, 4]),
    "l2": light([-3, 2, 4]),
    "l3": light([0, -3, 3]),
    "l4": light([2, 0.5, -1]),
})


def cpu():
    t = os.times()
    return t.user + t.system


dr.eval(mi.render(scene, spp=1))  # warm-up: compiles the kernels
walls, cpus = [], []
for i in range(frames):
    t0, c0 = time.perf_counter(), cpu()
    img = mi.render(scene, spp=1, seed=i + 1)
    dr.eval(img)
    dr.sync_thread()
    walls.append(time.perf_counter() - t0)
    cpus.append(cpu() - c0)
print(f"{variant} {dist}: wall {1000 * sum(walls) / frames:.1f} ms/frame (best {1000 * min(walls):.1f} ms), "
      f"CPU {1000 * sum(cpus) / frames:.1f} ms/frame")
