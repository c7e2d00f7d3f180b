"""The figures that compare estimators on one dataset, split by idea.

``common``       one time axis per dataset (t - t0), log axes with readable ticks, legends,
                 layout that leaves room for a figure's title and legend, saving;
``aligned``      each run's trajectory aligned to the reference exactly as its ATE is;
``overlay``      the reference and every estimator on one top view; one estimator's path
                 coloured by its error;
``error``        aligned position error over time of every estimator on one axes; per-axis
                 pose errors with +/-3 sigma;
``consistency``  NEES and NIS per dof with one chi-square band per distinct dof.

``workbench.report_plots`` assembles them per dataset (``write_dataset_plots``);
``workbench.plots`` draws a single run folder's own figures with the same helpers. Every
helper comes in a pair, as in GTSAM's python: ``*_on_axes`` draws on given axes, the
``*_figure`` wrapper makes the figure and returns it with its file name.
"""
