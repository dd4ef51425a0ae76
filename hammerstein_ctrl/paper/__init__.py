"""The paper's material, in one layer that the general code never imports.

* :mod:`~hammerstein_ctrl.paper.presets`: the TRS and EMPS cases (record,
  structure, the paper's initial point, optimiser settings and numbers);
* :mod:`~hammerstein_ctrl.paper.settings`: the paper's optimiser settings
  (gains, bounds, Eq. 8's test objective);
* :mod:`~hammerstein_ctrl.paper.datasets`: the EMPS benchmark files (columns
  ``t``, ``vir``, ``qm``) and the TRS reconstruction;
* :mod:`~hammerstein_ctrl.paper.study`: repeated independent trials of the
  paper's methods on a case, resumable, with the paper's comparison;
* :mod:`~hammerstein_ctrl.paper.report`: the comparison tables next to the
  paper's numbers;
* :mod:`~hammerstein_ctrl.paper.emps_loop`: the EMPS as a Lur'e loop: its
  position controller from the gains in the files, the published physical
  parameters, the record and its loop (``load_emps_loop``).

The package namespace keeps the short names (``hc.presets``, ``hc.load_emps``,
``hc.run_study``, ...); the command line and the benchmarks use this layer.
"""
