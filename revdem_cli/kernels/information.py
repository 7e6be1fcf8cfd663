"""The information an entry of the tape holds (`kernels.tape`): doubles numbered as
integers in their order, so that an entry counts the doubles between two values, and the
bits of such a count, or of a difference on a history's grid."""

import numpy as np

from revdem_cli.kernels import inline


@inline
def ordered(bits):
    """The bits of a double as an integer in the order of the doubles: consecutive doubles
    are consecutive integers, -0.0 is -1 and +0.0 is 0."""
    return bits if bits >= 0 else ~(bits & np.int64(0x7FFFFFFFFFFFFFFF))


@inline
def unordered(number):
    """The bits of the double that `ordered` numbers so."""
    return number if number >= 0 else (~number) | np.int64(-0x8000000000000000)


@inline
def bits_of(amount):
    """log2(1 + 2|amount|): the bits that tell an integer from the others of at most its size."""
    return np.log2(1.0 + 2.0 * abs(float(amount)))


@inline
def grid_spread(was, now, step):
    """2|was - now| / step, where a history entry (the doubles' bits `was` and `now`) lies
    on its contact's grid of `step`; with no grid (step 0, a contact apart), 2|amount| in
    doubles (as `bits_of`): what `grid_bits` takes the logarithm of."""
    if step == 0.0:
        return 2.0 * abs(float(ordered(was) - ordered(now)))
    apart = abs(np.int64(was).view(np.float64) - np.int64(now).view(np.float64))
    return 2.0 * apart / step


@inline
def grid_bits(was, now, step):
    """log2(1 + 2|was - now| / step): the bits of a history entry on its contact's grid
    (`grid_spread`)."""
    return np.log2(1.0 + grid_spread(was, now, step))
