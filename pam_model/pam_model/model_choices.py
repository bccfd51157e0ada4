"""The named choices of the model: friction laws (MODEL.md section 6, Table III) and muscle force
models (eqs. (6), (7) and two simplifications).

Users select a choice by its lower-case name: the parameters friction_law / force_model of
sim_node and ukf_node, the --friction / --force options of the pam-* tools, PamModel(friction=...,
force=...). The numba kernels of pam_model.physics take the integer value: pass ``int(law)``.
The values are frozen into numba's on-disk cache of those kernels, which watches physics.py only:
never renumber a member. A new choice takes the next free value and a branch in both physics
paths (the vectorised path raises NotImplementedError without one, so test_paths_agree fails).

Only the standard library is imported here: node configs list the names for their parameter
checks and --help without loading numba.
"""

from __future__ import annotations

import re
from enum import IntEnum
from numbers import Integral


class ModelChoice(IntEnum):
    """An IntEnum whose members users name in lower case ('proposed', 'no_offset')."""

    def __str__(self) -> str:
        return self.name.lower()

    def __format__(self, spec: str) -> str:
        return format(str(self), spec)   # f'{law}' is the name too, not the number

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The names users may pass, in the order of the integer values."""
        return tuple(str(member) for member in cls)

    @classmethod
    def kind(cls) -> str:
        """What a member is, from the class name: 'friction law', 'force model'."""
        return re.sub(r'(?<!^)(?=[A-Z])', ' ', cls.__name__).lower()

    @classmethod
    def unknown(cls, value) -> ValueError:
        """The error for a value that is no member: it lists every valid name."""
        return ValueError(f'unknown {cls.kind()} {value!r}; choose one of: '
                          f'{", ".join(cls.names())}')

    @classmethod
    def from_name(cls, name: str):
        """The member a user's name selects; ValueError (listing the names) for any other."""
        for member in cls:
            if isinstance(name, str) and name == str(member):
                return member
        raise cls.unknown(name)

    @classmethod
    def coerce(cls, value):
        """The member for a member, its name or its integer value; ValueError for anything else
        (a bool, another enumeration's member, an unknown name or number)."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            return cls.from_name(value)
        if isinstance(value, Integral) and not isinstance(value, (bool, ModelChoice)):
            try:
                return cls(int(value))
            except ValueError:
                pass
        raise cls.unknown(value)


class FrictionLaw(ModelChoice):
    """Friction torque T_f of the joint (Table III); all go through Kikuuwe's form of eq. (10)."""

    PROPOSED = 0   # eq. (10): shaft Coulomb + pressure-dependent tube friction + viscous c_s
    LINEAR = 1     # viscous only, c_s
    COULOMB = 2    # simple Coulomb force F_r at the shaft radius
    TONDU = 3      # Tondu's static-to-kinetic exponential, f_s, f_k, xdot_k
    NONE = 4       # no friction


class ForceModel(ModelChoice):
    """Contraction force F_i of a muscle."""

    PROPOSED = 0             # eqs. (6), (7): F = v(l) P + w(l)
    LENGTH_INDEPENDENT = 1   # coefficients frozen at l = L0
    NO_OFFSET = 2            # w = 0: F = v(l) P
