"""helpers.notebook: Claims (strict at defaults, a note otherwise) and show_source."""
import pytest

from helpers.notebook import Claims, show_source, source_lines


def test_claims_raise_at_defaults_and_report_otherwise(capsys):
    strict = Claims({"SEED": 0, "GATE": 0.99}, SEED=0, GATE=0.99)
    assert strict.at_defaults and strict.check(1 < 2, "one is below two")
    with pytest.raises(AssertionError, match="the text claims: two is below one"):
        strict.check(2 < 1, "two is below one")
    relaxed = Claims({"SEED": 3, "GATE": 0.99}, SEED=0, GATE=0.99)
    assert relaxed.changed == ["SEED"]
    assert relaxed.check(2 < 1, "two is below one") is False
    relaxed.check(2 < 1, "two is below one")  # reported once
    out = capsys.readouterr().out
    assert out.count("no longer holds: two is below one") == 1 and "SEED" in out


@pytest.mark.parametrize("args, kwargs, message", [
    ((["not", "a", "dict"],), {"SEED": 0}, "globals"),
    (({},), {}, "at least one parameter"),
    (({"SEED": 0},), {"SEED": 0, "GATE": 1}, "not defined"),
])
def test_claims_bad_input(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        Claims(*args, **kwargs)


def test_claims_bad_claim_text():
    with pytest.raises(ValueError, match="claim"):
        Claims({"A": 1}, A=1).check(True, "")


def test_source_is_the_running_code(capsys):
    text = source_lines(Claims.check)
    assert text.startswith("def check(self, condition: object, claim: str) -> bool:")
    show_source(Claims.check, start="ok = bool", stop="return ok")
    with pytest.raises(ValueError, match="no line"):
        show_source(Claims.check, start="no such text")
    with pytest.raises(ValueError, match="no Python source"):
        source_lines(len)
