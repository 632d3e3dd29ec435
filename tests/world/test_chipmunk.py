"""The world's one use of pymunk internals (world/chipmunk.py) fails loudly on a pymunk
whose internals differ: the version is in the pinned range, the Chipmunk symbols exist,
and the C calls give exactly what pymunk's public API gives."""

from __future__ import annotations

import numpy as np
import pymunk

from world import chipmunk as cp


def test_pymunk_is_in_the_pinned_range_and_its_cffi_binding_has_what_the_world_calls():
    assert cp.version_ok(), f"pymunk {pymunk.version} is outside {cp.PYMUNK_RANGE}: re-check world/chipmunk.py"
    assert not cp.version_ok("8.0.0") and cp.version_ok("7.3.1")
    for name in ("cpSpaceStep", "cpSpaceSegmentQueryFirst", "cpSpacePointQueryNearest"):
        assert hasattr(cp.lib, name), name


def scene():
    rng = np.random.default_rng(3)
    space = pymunk.Space()
    for _ in range(15):
        a, b = rng.uniform(0, 2, 2), rng.uniform(0, 2, 2)
        space.add(pymunk.Segment(space.static_body, tuple(a), tuple(b), float(rng.uniform(0, 0.02))))
    for _ in range(5):
        body = pymunk.Body(body_type=pymunk.Body.STATIC)
        body.position = tuple(rng.uniform(0.2, 1.8, 2))
        space.add(body, pymunk.Circle(body, float(rng.uniform(0.02, 0.1))))
    return space, rng


def test_a_ray_cast_and_a_nearest_point_query_equal_the_public_api():
    space, rng = scene()
    sp, info, pinfo = cp.cp_space(space), cp.segment_info(), cp.point_info()
    f = pymunk.ShapeFilter()
    cf = cp.shape_filter(0, f.categories, f.mask)
    for _ in range(300):
        p, q = tuple(rng.uniform(0, 2, 2)), tuple(rng.uniform(0, 2, 2))
        hit = space.segment_query_first(p, q, 0.0, f)
        cp.segment_query_first(sp, cp.vect(*p), q, 0.0, cf, info)
        assert (info.alpha if info.shape != cp.ffi.NULL else 1.0) == (hit.alpha if hit else 1.0)
        near = space.point_query_nearest(p, 0.5, f)
        cp.point_query_nearest(sp, p, 0.5, cf, pinfo)
        if near is None:
            assert pinfo.shape == cp.ffi.NULL
        else:
            assert pinfo.distance == near.distance


def test_a_c_step_equals_a_public_step():
    def run(c_step: bool) -> list[tuple[float, float]]:
        space, rng = scene()
        bodies = []
        for _ in range(6):
            b = pymunk.Body(0.08, pymunk.moment_for_circle(0.08, 0, 0.03))
            b.position = tuple(rng.uniform(0.3, 1.7, 2))
            b.velocity = tuple(rng.uniform(-0.2, 0.2, 2))
            space.add(b, pymunk.Circle(b, 0.03))
            bodies.append(b)
        space.step(0.008)  # the wrapper's first step validates the bodies, as the world does
        for _ in range(200):
            cp.space_step(cp.cp_space(space), 0.008) if c_step else space.step(0.008)
        return [tuple(b.position) for b in bodies]

    assert run(True) == run(False)
