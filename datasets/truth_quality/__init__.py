"""Truth quality as data: where a truth stream (Vicon, GPS, a bag's truth topic) cannot be
trusted, as typed time intervals that scoring leaves out.

``assess_truth(t, positions, rotations, motion, settings)`` looks at any truth stream,
planar or 3-D poses or positions only, and returns a ``TruthQuality`` whose intervals each
say what was found (``TruthKind``), when, and the numbers that found it:

* ``dropout``: a time gap longer than ``dropout_min_steps`` median steps. The interval
  spans the *missing* samples (one median step after the last sample before the gap to
  one before the first sample after it), so no real sample is dropped.
* ``rate_change``: at least ``rate_change_min_steps`` consecutive steps all longer than
  ``rate_change_factor`` median steps, or all shorter than 1 / ``rate_change_factor``.
* ``freeze``: the same value (every coordinate bit for bit) held for at least
  ``freeze_min_steps`` steps while time advances, and the stream moved across it (the step
  out of the held value is itself a jump). The first held sample is the real value at its
  time; the interval spans the stale ones. A vehicle standing still is not a freeze.
* ``jump``: a step (or a run of steps) in position or rotation that the stream's own
  motion cannot explain (see below) and that no later opposite jump undoes: the interval
  spans the samples around it (which side is wrong cannot be told).
* ``wrong_track``: the samples between a jump away and a later opposite jump back, however
  smooth the track is in between (a Vicon marker set fitted to the wrong markers moves
  smoothly with the robot). Opposite: in some part significant in both, the return points
  within ``acos(pair_min_cosine)`` of the reverse of the departure, whatever its size (a
  drifting offset leaves at 0.3 m and returns from 2.7 m). Pairs nest and never cross;
  exact ones (``pair_exact_remainder``) are taken first, then the shortest. A spike, a
  run of unexplained steps that cancel (``spike_max_net_fraction``; headings modulo a
  full turn, so a heading interpolated the long way round across +-pi is one), is a
  wrong track of the samples inside it. Limits: without odometry, a wrong track whose
  offset turns by more than 60 degrees between its edges, or whose edges are ramps rather
  than steps, is not bound (its edges stay jumps, or go unseen).
* ``heading`` (planar truth by default): for a sustained time while moving, the heading
  disagrees with the direction of travel of the truth's own positions by more than
  ``heading_max_angle_rad`` (a large body-frame lateral or backward velocity). Assumption:
  the vehicle drives forward (a car, a differential-drive robot); switch the check off
  (``heading_check=False``) for a vehicle that reverses or strafes.
* ``motion`` (only with ``motion``, the vehicle's odometry increments, independent of the
  truth): over short windows, the truth's relative motion differs from the odometry's by
  more than ``motion_min_spreads`` robust spreads (1.4826 x median absolute deviation) of
  that difference over the whole recording. A few percent of odometry calibration error
  moves the median and widens the spread; it does not trigger the check. Overlapping
  flagged windows make one disagreement whose net change (the truth's motion beyond the
  odometry's) pairs like a jump: a smooth departure and its return bound a wrong track.
  Edges are known to a window (``motion_window_steps``), not to a sample.

How a step is judged (the same for positions and rotations): the local velocity is the
median of the velocities over ``2 jump_window_steps + 1`` steps around it; the step's
residual is its difference from that velocity times its duration. A jump is a residual
larger than every one of: ``jump_min_sigmas`` robust sigmas of the residuals over the
whole stream (its noise), ``jump_min_fast_steps`` times the stream's fast step (the
``fast_step_percentile`` percentile of the step lengths: a change of velocity of several
times the vehicle's fast speed within one sample is not driving), and a resolution floor.
Every threshold is therefore a multiple of the stream's own statistics; the defaults hold
for any rate and any vehicle speed. The thresholds actually used are in
``TruthQuality.thresholds``.

Intervals are closed, ``[start_s, end_s]`` on the truth's clock; ``keep_mask`` says which
times lie outside all of them. ``datasets.state.GroundTruth.excluded`` carries them to the
metrics, which score nothing inside them.

Modules: ``intervals`` (``TruthKind``, ``TruthInterval`` and their union), ``settings``
(``TruthQualitySettings``), ``quality`` (``TruthQuality``, what an assessment found),
``steps`` (how a step is judged), one module per check (``timing``: dropouts and rate
changes, ``freezes``, ``jumps``: bursts as jumps or spikes, ``pairing``: wrong tracks,
``heading``, ``motion``), and ``assess`` (``assess_truth``, ``assess_trajectory``: the
checks in order).
"""
