from atemr.errors import AtemrError, ConfigError, HardwareError, NavigationError, ProtocolError


def test_config_error_formats_its_place():
    e = ConfigError("unknown key 'x'", file="agent.yaml", line=42, column=7, path="states.EXEC.tree")
    assert str(e) == "agent.yaml:42:7 states.EXEC.tree: unknown key 'x'"
    assert str(ConfigError("bad", path="environment ATEMR_X")) == "environment ATEMR_X: bad"
    assert str(ConfigError("bad")) == "bad"


def test_hierarchy_and_criticality():
    for cls in (ConfigError, ProtocolError, HardwareError, NavigationError):
        assert issubclass(cls, AtemrError)
    err = HardwareError("no answer for 0.5 s", component="left motor", critical=True)
    assert err.critical and err.component == "left motor" and str(err) == "left motor: no answer for 0.5 s"
    assert not NavigationError("no path").critical
