"""Where the suite's heaviest timed runs go among pytest's workers."""

import pytest

#: The sweeps that run many timed processes at once go to one pytest worker, one after another
#: (pyproject's `--dist loadgroup`): side by side on CI's two cores they starved each other, and
#: the embedded reference's RSP cases came out inconclusive ("the harness's event loop was held").
SWEEPS = pytest.mark.xdist_group("sweeps")
