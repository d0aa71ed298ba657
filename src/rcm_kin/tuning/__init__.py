"""Model-based gains tuned by simulation over what the model does not know.

- :mod:`.draws`: the plants a design is judged on, drawn from the identified uncertainty and
  consistent with the measured holds, each with its frozen-gain firmware loops;
- :mod:`.design`: the firmware law's gains, feedforwards and compensation as bounded design
  parameters (a fixed and a scheduled space), written into gain tables;
- :mod:`.objective`: a controller's outcomes over the draws and the score against the thesis law;
- :mod:`.optimise`: differential evolution (seeded, time-budgeted, forked workers) over a space;
- :mod:`.study`: the whole design: tune, judge on the tuning draws and on held-out ones, choose.
"""

import lazy_loader

__all__ = ["DesignSpace", "DesignStudy", "DrawSet", "Outcomes", "build_draws", "design_study", "evaluate",
           "minimise", "tune", "tuned_controller", "tuned_schedule"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "design": ["DesignSpace", "tuned_schedule"],
        "draws": ["DrawSet", "build_draws"],
        "objective": ["Outcomes", "evaluate"],
        "optimise": ["minimise", "tune", "tuned_controller"],
        "study": ["DesignStudy", "design_study"],
    },
)
