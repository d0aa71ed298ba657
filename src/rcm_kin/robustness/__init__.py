"""How robust a controller is to what the model does not know: Monte Carlo over the parameter
uncertainty, run on Dask.

- :mod:`.sampling`: the uncertain parameters, their spreads, and parameter sets drawn from them
  (one seed per sample);
- :mod:`.task`: one batch of samples simulated with every controller (what a Dask task runs);
- :mod:`.execution`: the batches on a ``dask.distributed`` cluster (embedded or remote);
- :mod:`.statistics`: the distributions over the samples, as dataclasses;
- :mod:`.figures`: empirical CDFs of the errors and margins;
- :mod:`.sweeps`: the design sweeps (counterweights, LQR/LQI budgets) on the same cluster.
"""

import lazy_loader

__all__ = ["Robustness", "Study", "run_in_process", "run_robustness", "uncertain_parameters"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "task": ["Study"],
        "execution": ["run_robustness", "run_in_process"],
        "statistics": ["Robustness"],
        "sampling": ["uncertain_parameters"],
    },
)
