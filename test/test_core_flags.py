"""Per-sample status flags (core/physics/flags.py): distinct bits and their readable form."""

from pma_model_ros.core.physics.flags import describe, Flag


def test_each_flag_is_its_own_bit():
    bits = [int(f) for f in Flag if f]
    assert all(b & (b - 1) == 0 for b in bits) and len(set(bits)) == len(bits)


def test_describe_names_every_set_flag():
    assert describe(0) == 'OK'
    assert describe(Flag.CLIPPED | Flag.EXTRAPOLATED) == 'CLIPPED|EXTRAPOLATED'
