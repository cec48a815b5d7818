"""beyond and on_a_face: a cube pushed past a line, lying on a face (not tipped on an edge)."""

import math

from bicoord_drake.models.scene import TABLE_TOP
from bicoord_drake.stages import predicates as P
from tests.stages.helpers import pose, quat_about, scene, state


def test_beyond_reads_the_centre_along_one_axis():
    sc = scene()  # 'small' is a 4 cm cube at x = -0.1
    z = TABLE_TOP + 0.02
    out = P.beyond("small", -0.15)
    assert not out(state(sc))
    assert out(state(sc, poses={"small": pose(-0.16, 0.0, z)}))
    assert not out(state(sc, poses={"small": pose(-0.15, 0.3, z)}))  # on the line: not past
    assert not out(state(sc, poses={"small": pose(-0.10, 0.0, z)}))  # only its edge past
    # the other direction and another axis
    assert P.beyond("small", -0.12, below=False)(state(sc))
    assert not P.beyond("small", -0.05, below=False)(state(sc))
    assert P.beyond("small", 0.05, axis="y", below=False)(
        state(sc, poses={"small": pose(-0.1, 0.06, z)})
    )
    assert "x < -0.15" in repr(out)


def test_on_a_face_accepts_any_face_down_and_rejects_an_edge():
    sc = scene()
    z = TABLE_TOP + 0.02
    face = P.on_a_face("small")
    assert face(state(sc))
    assert face(state(sc, poses={"small": pose(-0.1, 0.0, z, quat_about("x", math.pi / 2))}))
    assert face(state(sc, poses={"small": pose(-0.1, 0.0, z, quat_about("y", -math.pi / 2))}))
    assert face(state(sc, poses={"small": pose(-0.1, 0.0, z, quat_about("z", 0.7))}))  # yawed
    assert face(state(sc, poses={"small": pose(-0.1, 0.0, z, quat_about("x", math.radians(10)))}))
    on_edge = pose(-0.1, 0.0, TABLE_TOP + 0.028, quat_about("y", math.pi / 4))
    assert not face(state(sc, poses={"small": on_edge}))
    leaning = pose(-0.1, 0.0, z, quat_about("x", math.radians(25)))
    assert not face(state(sc, poses={"small": leaning}))
