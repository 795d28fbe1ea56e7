"""The node's parameters (``msg_adapters.config``): each declared once with a rule from
``contact_sim.validate`` (the engine settings' rules), its ROS descriptor derived from that rule,
every value checked by it and refused naming the parameter. No node is started."""
import re

import pytest

pytest.importorskip("rclpy", reason="ROS 2 Jazzy wheels not installed (make test installs them)")
pytestmark = pytest.mark.ros

from rclpy.parameter import Parameter  # noqa: E402

from contact_sim.validate import Number  # noqa: E402
from msg_adapters.config import DECLARED, PARAMETERS, ConfigError, validate_config  # noqa: E402


def _defaults():
    return {name: None if isinstance(p.default, Parameter.Type) else p.default for name, p in DECLARED.items()}


def test_the_defaults_pass_and_every_parameter_has_a_rule_and_a_derived_descriptor():
    cfg = validate_config(_defaults())
    assert cfg["tracked_bodies"] == [] and cfg["robot_base_pose"] is None and cfg["model_overrides"] == {}
    assert set(PARAMETERS) == set(DECLARED)
    for name, p in DECLARED.items():
        default, desc = PARAMETERS[name]
        assert default is p.default and desc.read_only == p.read_only and desc.description == p.description
        r = p.rule
        if isinstance(r, Number) and r.ge is not None and r.le is not None:
            span = desc.integer_range if r.integer else desc.floating_point_range
            assert (span[0].from_value, span[0].to_value) == (r.ge, r.le), name


@pytest.mark.parametrize("name", [n for n, p in DECLARED.items() if isinstance(p.rule, Number) and p.rule.le is not None])
def test_a_number_beyond_its_range_is_refused_by_name(name):
    rule = DECLARED[name].rule
    values = _defaults()
    values[name] = rule.le + 1
    with pytest.raises(ConfigError, match=re.escape(f"parameter {name}: must be <= {rule.le:g}")):
        validate_config(values)
    values[name] = True   # a boolean is no number, for an integer parameter too
    with pytest.raises(ConfigError, match=rf"parameter {name}: must be a"):
        validate_config(values)
    values[name] = rule.le   # the bound itself is in
    assert validate_config(values)[name] == rule.le


@pytest.mark.parametrize("name, bad, message", [
    ("scene", " ", "must be a scene file or a shipped scene"),
    ("frame_id", 3, "must be a string"),
    ("publish_markers", "yes", "must be true or false"),
    ("tracked_bodies", ["lid", "lid"], "names must be unique"),
    ("tracked_bodies", ["lid", ""], "must be a list of body names"),
    ("robot_disable_collisions", ["a:b:c"], "each pair is 'a:b'"),
    ("robot_base_pose", [0, 0, 0, 0, 0, 0, 2.0], "a unit quaternion"),
    ("model.contact_margin", float("nan"), "must be a finite number"),
])
def test_other_bad_values_are_refused_by_their_rule(name, bad, message):
    values = _defaults()
    values[name] = bad
    with pytest.raises(ConfigError, match=rf"parameter {name}: .*{message}"):
        validate_config(values)


def test_model_overrides_are_checked_by_the_engine_settings_rules():
    values = _defaults()
    values["model.toi"] = "sometimes"
    with pytest.raises(ConfigError, match="parameter model.toi: must be one of"):
        validate_config(values)
    values["model.toi"], values["model.contact_margin"], values["model.friction"] = " Swept ", 0.002, "false"
    assert validate_config(values)["model_overrides"] == {"toi": "swept", "friction": False, "contact_margin": 0.002}
