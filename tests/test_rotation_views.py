"""pydrake's ``RotationMatrix.col`` / ``.row`` return views into the matrix's memory: on a
temporary (``(A @ B).col(0)``, ``f().rotation().col(0)``) that memory is freed at once and the
first entries read back as allocator data (drake 1.51). The package takes them only from
named objects that stay alive; ``.matrix()`` and ``.translation()`` copy."""

import re
from pathlib import Path

import numpy as np
from pydrake.all import RigidTransform, RollPitchYaw

ROOT = Path(__file__).resolve().parents[1]
#: `.col(` / `.row(` whose receiver is a name (``X``, ``g.X_WG``), optionally ``.rotation()``.
NAMED = re.compile(r"(?<![\w\)\]\.])[A-Za-z_]\w*(\.[A-Za-z_]\w*)*(\[[\w\"']+\])?(\.rotation\(\))?$")


def views_on_temporaries(text: str) -> list[str]:
    """Lines of `text` that take ``.col(`` / ``.row(`` of something other than a name."""
    bad = []
    for line in text.splitlines():
        code = line.split("#", 1)[0]
        for m in re.finditer(r"\.(col|row)\(", code):
            if not NAMED.search(code[: m.start()]):
                bad.append(line.strip())
    return bad


def test_views_of_a_named_rotation_read_its_entries():
    X = RigidTransform(RollPitchYaw(0.1, 0.2, 0.3), [1.0, 2.0, 3.0])
    assert np.allclose(X.rotation().col(0), X.rotation().matrix()[:, 0])


def test_the_scan_finds_views_of_temporaries_and_passes_named_ones():
    assert views_on_temporaries("a = (turn @ R).col(0)\nb = f(x).rotation().row(1)") == [
        "a = (turn @ R).col(0)",
        "b = f(x).rotation().row(1)",
    ]
    assert views_on_temporaries("a = X.rotation().col(0)\nb = g.X_WG.rotation().col(2)") == []
    assert views_on_temporaries("c = before[side].rotation().col(0)") == []


def test_no_code_takes_a_view_of_a_temporary_rotation():
    found = {
        str(path.relative_to(ROOT)): bad
        for folder in ("bicoord_drake", "benchmarks", "scripts", "tests")
        for path in sorted((ROOT / folder).rglob("*.py"))
        if path.name != Path(__file__).name and (bad := views_on_temporaries(path.read_text()))
    }
    assert not found, f"copy first (.matrix()[:, k]) or name the owner: {found}"
