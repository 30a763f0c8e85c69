"""`quieted`: loggers raised for a while and given back their own levels, even when the block fails."""

import logging

import pytest

from atemr.logsetup import quieted


def test_quieted_raises_the_loggers_and_restores_them():
    a, b = logging.getLogger("test.quieted.a"), logging.getLogger("test.quieted.b")
    a.setLevel(logging.DEBUG)
    with quieted("test.quieted.a", "test.quieted.b"):
        assert a.level == b.level == logging.ERROR
    assert (a.level, b.level) == (logging.DEBUG, logging.NOTSET)
    with pytest.raises(RuntimeError), quieted("test.quieted.a", level=logging.WARNING):
        assert a.level == logging.WARNING
        raise RuntimeError("the block failed")
    assert a.level == logging.DEBUG
