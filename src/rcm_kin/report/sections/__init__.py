"""The report's sections: each module computes one section's data (a frozen dataclass of
tables, numbers and the paths of the files it wrote, relative to the report folder) by calling
the library; :mod:`rcm_kin.report.render` turns it into HTML with the section's template.

- :mod:`.robots`: drawings and meshcat pages of the bundled robots;
- :mod:`.models`: joints, link masses and the kinematic self-checks;
- :mod:`.gravity`: holding-effort maps, drive parameters, counterweight designs;
- :mod:`.schedule`: the model-based gain schedule beside the thesis's tables;
- :mod:`.linear_models`: the linear models of the schedule's grid;
- :mod:`.tracking`: the thesis's tracking experiments on the model;
- :mod:`.safety`: CBF filters, RCM of each chain, SOS certificates;
- :mod:`.measured`: calibration, identification and grey-box fit on measured logs.
"""
