import pytest

from atemr.errors import AtemrError, RegistryError
from atemr.registry import Registry


def test_register_by_decorator_and_lookup():
    reg: Registry[type] = Registry("behaviours")

    @reg.register()
    class GoToPose:
        pass

    @reg.register("wait")
    class Wait:
        pass

    assert reg.get("GoToPose") is GoToPose and reg.get("wait") is Wait
    assert list(reg) == ["GoToPose", "wait"] and len(reg) == 2 and "wait" in reg


def test_unknown_name_suggests_close_names():
    reg: Registry[int] = Registry("behaviours")
    reg.add("GoToPose", 1)
    reg.add("FollowPath", 2)
    with pytest.raises(RegistryError, match=r"unknown behaviours 'GoToPos' \(did you mean 'GoToPose'\?\)"):
        reg.get("GoToPos")
    assert issubclass(RegistryError, AtemrError)


def test_a_name_cannot_be_taken_twice_by_different_objects():
    reg: Registry[object] = Registry("buses")
    a = object()
    reg.add("x", a)
    reg.add("x", a)  # re-registering the same object (module re-import) is fine
    with pytest.raises(RegistryError, match="already registered"):
        reg.add("x", object())


def test_entry_points_are_loaded(monkeypatch):
    class FakeEP:
        name = "plugin"
        value = "pkg:thing"

        def load(self):
            return "loaded"

    class BrokenEP(FakeEP):
        name = "broken"

        def load(self):
            raise ImportError("missing dependency")

    import atemr.registry as registry_module

    fake = {"atemr.things": [FakeEP(), BrokenEP()]}
    monkeypatch.setattr(registry_module, "entry_points", lambda group: fake.get(group, []))
    reg: Registry[str] = Registry("things")
    assert reg.get("plugin") == "loaded"
    assert "broken" not in reg  # a broken plugin is logged, not fatal
