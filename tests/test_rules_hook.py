"""Rules behind one hook (issue 17 item 4): each rule a frozen config with a judge() and its own carry,
the pipeline a loop over them, a new comparison rule one class, profile defaults on the dataclasses."""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.config import dump_profile, load_profile
from mav_motor_health.diagnosis import diagnose_motor
from mav_motor_health.diagnosis.profile import ThresholdProfile
from mav_motor_health.diagnosis.rules import COMPARE_RULES, BalanceRule, DynamicRule, StepRule, compare_rule
from mav_motor_health.diagnosis.rules.base import CompareRule, Frame
from mav_motor_health.diagnosis.rules.step import StepCarry
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.errors import ConfigError
from mav_motor_health.model.equations import steady_state

SHIPPED = ("testbed", "flight", "flight_base", "flight_dynamic", "flight_dynamic_base", "flight_vehicle")


def test_each_kind_is_its_own_class_with_only_its_settings():
    assert COMPARE_RULES["step"] is StepRule
    assert COMPARE_RULES["dynamic"] is DynamicRule
    assert COMPARE_RULES["balance"] is BalanceRule
    assert "lag_fraction" in {f.name for f in fields(DynamicRule)}
    assert "lag_fraction" not in {f.name for f in fields(BalanceRule)}
    assert "slow_factor" not in {f.name for f in fields(StepRule)}
    assert isinstance(compare_rule("balance", residual_tau_s=0.2), BalanceRule)
    with pytest.raises(ConfigError) as info:
        compare_rule("balance", lag_fraction=1.0)
    assert info.value.key == "steady.lag_fraction" and "'dynamic'" in str(info.value)
    with pytest.raises(ConfigError) as info:
        compare_rule("kalman")
    assert info.value.key == "steady.kind" and "balance" in str(info.value)
    with pytest.raises(ConfigError) as info:
        BalanceRule(residual_tau_s=0.0)  # validated when made, whoever makes it
    assert info.value.key == "steady.residual_tau_s"


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_profiles_write_and_read_back_exactly(tmp_path: Path, name: str):
    profile = load_profile(name)
    path = tmp_path / f"{name}.toml"
    path.write_text(dump_profile(profile))
    assert load_profile(path) == profile
    assert [rule.name for rule in load_profile(path).rules] == [rule.name for rule in profile.rules]


def test_defaults_live_on_the_dataclasses(tmp_path: Path):
    """An empty profile file is the dataclasses' defaults, whatever the loader once repeated."""
    path = tmp_path / "empty.toml"
    path.write_text("")
    assert load_profile(path) == ThresholdProfile(name="empty")
    path.write_text('[steady]\nkind = "balance"\n')
    assert load_profile(path).steady == BalanceRule()


def test_the_pipeline_is_the_profiles_rules_in_order():
    names = [rule.name for rule in load_profile("flight_vehicle").rules]
    assert names[0] == "compare" and names[-1] == "persistence"
    assert names.index("tree") < names.index("slow_look") < names.index("judged") < names.index("sequential")
    assert "sequential" not in [rule.name for rule in load_profile("flight").rules]  # its test is off


@dataclass(frozen=True)
class OffsetRule(StepRule):
    """A comparison rule written outside the package: the step rule's model shifted by ``offset_rad_s``
    (what a user trying a model correction would write). One class, one kind, nothing else to touch."""

    kind = "test_offset"

    offset_rad_s: float = 0.0

    def judge(self, frame: Frame, carries: list[StepCarry]) -> list[StepCarry]:
        new = super().judge(frame, carries)
        frame.omega_model_rad_s = frame.omega_model_rad_s + self.offset_rad_s
        frame.omega_expected_rad_s = frame.omega_model_rad_s
        return new


def test_a_new_comparison_rule_is_one_class_and_a_profile_names_it(tmp_path: Path, paper_motor):
    assert COMPARE_RULES["test_offset"] is OffsetRule and issubclass(OffsetRule, CompareRule)
    path = tmp_path / "offset.toml"
    path.write_text('[steady]\nkind = "test_offset"\noffset_rad_s = -60.0\n')
    shifted = load_profile(path)
    assert shifted.steady == OffsetRule(offset_rad_s=-60.0)
    # a healthy motor held at 9 V: the plain step rule finds it NORMAL; against a model 60 rad/s too
    # slow (three speed bands) it turns "too fast", which the tree cannot name (UNKNOWN)
    t = np.arange(0.0, 5.0, 0.01)
    v = np.full(t.size, 9.0)
    model = steady_state(paper_motor, v)
    plain, _ = diagnose_motor(paper_motor, load_profile("testbed"), t, v, model.omega_rad_s, model.current_a)
    moved, carry = diagnose_motor(paper_motor, shifted, t, v, model.omega_rad_s, model.current_a)
    assert plain["announced"][-1] == MotorState.NORMAL
    assert moved["announced"][-1] == MotorState.UNKNOWN
    np.testing.assert_allclose(moved["omega_model_rad_s"], plain["omega_model_rad_s"] - 60.0)
    # its carry is kept under the rule's name with every other rule's
    assert set(carry.rules) == {rule.name for rule in shifted.rules}
    assert isinstance(carry.rules["compare"], StepCarry)


RULE_MODULE = '''
from dataclasses import dataclass

from mav_motor_health.diagnosis.rules import StepRule


@dataclass(frozen=True)
class SlowSettleRule(StepRule):
    """An installed rule: the step rule, settling for at least ``min_settle_s``."""

    kind = "installed_slow_settle"
    min_settle_s: float = 1.0
'''


def test_a_rule_installed_by_another_package_is_found_by_its_kind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    (tmp_path / "demo_rules_mod.py").write_text(RULE_MODULE, encoding="utf-8")
    dist = tmp_path / "demo_rules-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: demo-rules\nVersion: 0.1\n", encoding="utf-8"
    )
    (dist / "entry_points.txt").write_text(
        "[mav_motor_health.rules]\nslow_settle = demo_rules_mod:SlowSettleRule\n", encoding="utf-8"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert "installed_slow_settle" not in COMPARE_RULES  # not imported until a profile names it
    path = tmp_path / "p.toml"
    path.write_text('[steady]\nkind = "installed_slow_settle"\nmin_settle_s = 2.5\nstep_v = 0.3\n')
    try:
        rule = load_profile(path).steady
        assert type(rule).__name__ == "SlowSettleRule" and rule.min_settle_s == 2.5  # type: ignore[attr-defined]
        assert rule.step_v == 0.3  # type: ignore[attr-defined]
    finally:
        COMPARE_RULES.pop("installed_slow_settle", None)
    path.write_text('[steady]\nkind = "not_installed"\n')
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert info.value.key == "steady.kind" and info.value.path == path
