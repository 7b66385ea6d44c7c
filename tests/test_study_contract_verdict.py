"""A claim's verdict: holds, fails, or not reproducible with this model (naming what the model
lacks) — derived from ``holds`` and ``missing``, written to the JSON and shown in the tables."""

import json

import pytest

from experiments.studies.study import Claim, StudyResult, verdict_cell
from tests.helpers import assert_study_contract


def test_verdicts_follow_holds_and_missing():
    assert Claim("a", "s", 1, 1, True).verdict == "holds"
    assert Claim("b", "s", 1, 2, False).verdict == "fails"
    unreachable = Claim("c", "s", 1, 2, False, "n", missing="roller compliance")
    assert unreachable.verdict == "not reproducible with this model"
    assert verdict_cell(unreachable) == "**not reproducible** (lacks roller compliance)"
    assert verdict_cell(Claim("b", "s", 1, 2, False)) == "**no**"


def test_a_claim_that_holds_lacks_nothing():
    with pytest.raises(ValueError, match="holds, so nothing is missing"):
        Claim("a", "s", 1, 1, True, missing="rollers")


def test_the_json_and_the_table_carry_the_verdict():
    result = StudyResult("x", claims=[Claim("a", "s", 1, 1, True),
                                      Claim("c", "s", 1, 2, False, missing="rollers")],
                         runs={}, timing={})
    data = json.loads(json.dumps(result.to_json()))
    assert_study_contract(data)
    assert [c["verdict"] for c in data["claims"]] == ["holds",
                                                      "not reproducible with this model"]
    table = result.markdown()
    assert "1 of 2 claims reproduced" in table and "1 not reproducible with this model" in table
    assert "**not reproducible** (lacks rollers)" in table
    # an older JSON without the fields still renders
    assert verdict_cell({"holds": False}) == "**no**"
