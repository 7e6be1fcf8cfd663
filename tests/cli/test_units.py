"""A trajectory says its units as H5MD's units module does: SI, a `unit` attribute on each
dimensionful dataset, none on a pure number."""

import h5py


def test_a_trajectory_carries_its_units(smoke_run):
    with h5py.File(smoke_run / "collision_smoke.forward.h5") as f:
        assert f["h5md/modules/units"].attrs["system"] == b"SI"

        def unit(path):
            return f[path].attrs.get("unit")

        assert unit("particles/all/position/value") == b"m"
        assert unit("particles/all/velocity/value") == b"m s-1"
        assert unit("particles/all/angular_velocity/value") == b"rad s-1"
        assert unit("particles/all/force/value") == b"N"
        assert unit("particles/all/position/time") == b"s"
        assert (unit("particles/all/radius"), unit("particles/all/mass")) == (b"m", b"kg")
        assert unit("observables/kinetic_energy/value") == b"J"
        assert unit("observables/kinetic_energy/time") == b"s"
        assert unit("observables/coordination_number/value") is None
