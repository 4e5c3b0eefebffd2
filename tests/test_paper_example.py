"""The seed paper's verdicts (Theorem 1, Remark 11) from URDF + YAML."""

from __future__ import annotations

import numpy as np
import pytest

import cdpm


@pytest.fixture(scope="module")
def lin(paper_robot):
    return cdpm.linearise(paper_robot, "nominal")


def test_nominal_pose_is_poc_with_certificate(lin):
    result = cdpm.positive_output_controllability(
        lin.A, lin.B, lin.C, sign_constrained=lin.sign_constrained
    )
    assert result.verdict is cdpm.Verdict.YES
    assert bool(result)
    assert result.margin > 0
    assert result.certificate.verify(lin.A, lin.B, lin.C)


def test_remark_11_witness_gives_eq30(lin):
    result = cdpm.positive_controllability(lin.A, lin.B, sign_constrained=lin.sign_constrained)
    assert result.verdict is cdpm.Verdict.NO
    assert not bool(result)
    v = np.asarray(result.witness, dtype=float)
    v = v * (-2.0 / v[2])  # scale to the paper's (0, 0, -2, -1)
    np.testing.assert_allclose(v, [0, 0, -2, -1], atol=1e-12)
    np.testing.assert_allclose(lin.A.T @ v, 0.0, atol=1e-12)  # eigenvector of A^T, eigenvalue 0
    # eq 30: <v, B u> = -2.995 u2 - 0.666 u4 (three printed decimals)
    np.testing.assert_allclose(v @ lin.B, [0, -2.995, 0, -0.666], rtol=0, atol=0.5e-3)


def test_ranks_and_wrench_closure(lin):
    oc = cdpm.output_controllability(lin.A, lin.B, lin.C)
    assert oc.rank == 1 and oc.controllable
    kc = cdpm.controllability(lin.A, lin.B)
    assert kc.rank == 4 and kc.controllable
    # Every column of -L^T has a non-negative q2 component (0, 0.749, 0, 0.166):
    # no cable can produce a negative joint-2 torque, so no wrench closure.
    wc = cdpm.wrench_closure(lin.cable_jacobian)
    assert not bool(wc)
    np.testing.assert_allclose(-lin.cable_jacobian.T[1], [0, 0.7488, 0, 0.1664], atol=1e-4)


def test_neighbourhood_of_nominal_is_poc(paper_robot):
    # Paper, end of Section IV-C: all nearby equilibria are POC too.
    rng = np.random.default_rng(11)
    q0 = paper_robot.poses["nominal"]
    for dq in rng.uniform(-0.05, 0.05, size=(25, 2)):
        lin = cdpm.linearise(paper_robot, q0 + dq)
        result = cdpm.positive_output_controllability(lin.A, lin.B, lin.C)
        assert result.verdict is cdpm.Verdict.YES
        assert result.certificate.verify(lin.A, lin.B, lin.C)
