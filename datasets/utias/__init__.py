"""UTIAS Multi-Robot Cooperative Localization and Mapping (MRCLAM) loader: ``utias:FOLDER#robotN``.

Real planar data (Leung et al., IJRR 2011): one robot's odometry (forward velocity, angular
velocity), monocular range/bearing sightings of barcoded landmarks, Vicon ground truth of
the robot and surveyed landmark positions. Any MRCLAM dataset folder works (files
``Barcodes.dat``, ``Landmark_Groundtruth.dat``, ``RobotN_{Odometry,Measurement,Groundtruth}.dat``).

What the stream contains (time-ordered; at equal times motion first, then the scan):
- the odometry rows are the commanded velocities, calibrated at load against Vicon
  (``datasets.odometry_calibration.fit_scales_pooled``; ``metadata['odometry_scales']``): a
  turn-rate factor (``odometry_turn_scale``), and a speed factor times
  ``max(0, 1 - coupling |omega|)`` (``odometry_speed_scale``,
  ``odometry_speed_turn_coupling``), all ``fit`` by default. Dataset 1 overstates the turn
  by 4-7 % on every robot, and the speed the more the robot turns (by 40 % at 0.3-0.6
  rad/s); then:
- ``GyroSample(t, rate=[omega])`` for every odometry row (the rate input of gyro-driven
  estimators such as ``sensor-based``);
- ``Odometry(t, velocity=[v, omega])`` for every odometry row; the sample at ``t`` is meant
  for the interval ending at ``t`` (the workbench's convention, as in dead reckoning);
  ``covariance`` is the per-sample white-noise covariance ``diag(sigma_v^2, sigma_omega^2)``
  (the integrated increment over ``dt`` then has covariance ``dt^2 * covariance``);
- ``LandmarkScan`` of the sightings sharing one time: body-frame points by
  ``datasets.range_bearing`` (the unbiased converted measurement and
  its covariance by default; ``landmark_conversion=first-order``: ``p = r (cos b, sin b)``
  with ``J diag(sr^2, sb^2) J^T``).

Quirks handled (all counted in ``Sequence.counts``):
- *Rounded time column.* This copy is resampled on a 0.02 s grid but prints 5 significant
  digits, so after 1000 s the times are rounded to 0.1 s. When every printed odometry and
  ground-truth time is consistent with ``row index x grid_step_s`` within its printing
  resolution, the row index gives the time (``time_source='row_grid'``); measurement
  times are snapped to the grid and stay uncertain by +/-0.05 s after 1000 s. Otherwise
  (an original, irregular MRCLAM folder) the printed times are used, shifted to start at 0
  (``time_source='printed'``), and rows whose time does not increase are dropped.
- *Other robots' barcodes* (subjects 1-5, the MRCLAM robots) are not static landmarks:
  dropped. *Unknown barcodes* (not in ``Barcodes.dat``): dropped.
- *Stale repeats*: a sighting identical (range and bearing) to the previous sighting of the
  same barcode is a repeat of an old camera result: dropped (``drop_stale_repeats``).
- *Duplicate sightings*: the same barcode twice at one (snapped) time: the first is kept.
- *Out-of-range times*: sightings before the first or after the last odometry time cannot
  be used: trimmed, counted and warned (an edge of the recording, never an error; the
  ``max_dropped_fraction`` error applies to sightings going back in time inside it).
- *Vicon heading glitches*: the resampling interpolated some headings the long way round
  across +/-pi (runs of 1-5 samples). ``repair_heading_glitches`` replaces every run whose
  implied rate exceeds ``max_heading_rate_rad_s`` by the short-way interpolation between
  the good samples around it; the number of repaired samples is counted.
- *Swapped landmark labels*: in dataset 1 barcodes 18 and 61 (subjects 11 and 17) are
  swapped with respect to ``Landmark_Groundtruth.dat`` (the robots see barcode 18 where
  subject 17 is surveyed). The swap is detected from the data, not assumed
  (``detect_label_swaps``: a pair of barcodes whose sightings, placed with the Vicon poses,
  sit at each other's surveyed position), so another MRCLAM folder gets only the swaps its
  own data show; ``fix_swapped_labels=false`` keeps the file's labels. The metadata says
  which pairs were swapped.
- *Vicon failures*: ``datasets.truth_quality.assess.assess_truth`` judges the Vicon (headings
  repaired) against its own motion and the raw odometry: dropouts, freezes, jumps, wrong
  tracks between a jump away and back, headings against the direction of travel, motion
  the odometry contradicts. Its intervals are ``GroundTruth.excluded`` (scored nowhere,
  listed in the metadata's ``excluded_truth``, their total in ``Sequence.excluded_truth_s``,
  and warned), and no calibration fits on them.

Fitted at load (``datasets.utias.calibration``; ``calibration`` option): the odometry
calibration above, the odometry noise model (``odometry_noise``), the sightings'
correlation in time (``sighting_correlation``, ``datasets.sighting_correlation``) and the
camera's detection probability by range (``detection_probability``,
``datasets.detection_probability``), against the Vicon and survey of the folder's *other*
robots by default (``calibration=other-robots``: never the truth the run is scored on),
of the scored robot itself (``calibration=own-truth``: tuning on the test set, for
comparison) or not at all (``calibration=none``). Each is stated in ``Sequence.noise`` and
in the metadata (``Sequence.calibration`` says the source in one line), and each can be
switched off or given.

Ground truth: Vicon poses (heading repaired), world and body velocity by central
differences of the Vicon positions (derived, not measured), the surveyed landmark map
(ids = barcodes) and the true barcode of every sighting (``scan_ids``).

Modules: ``tables`` (the text files as numbers, the time base), ``recording`` (one robot's
streams, heading glitches, truth quality), ``sightings`` (barcodes, scans, label swaps),
``calibration`` (what is fitted, from which truth), ``options``, ``loader``.
"""

from datasets.utias.calibration import Calibration, calibrate
from datasets.utias.loader import describe, load, load_mrclam, parse_argument
from datasets.utias.options import UtiasOptions
from datasets.utias.recording import (
    Recording,
    read_recording,
    repair_heading_glitches,
    robots_in,
)
from datasets.utias.sightings import ROBOT_SUBJECTS, detect_label_swaps
from datasets.utias.tables import grid_times, printing_resolution, read_table

__all__ = [
    "ROBOT_SUBJECTS",
    "Calibration",
    "Recording",
    "UtiasOptions",
    "calibrate",
    "describe",
    "detect_label_swaps",
    "grid_times",
    "load",
    "load_mrclam",
    "parse_argument",
    "printing_resolution",
    "read_recording",
    "read_table",
    "repair_heading_glitches",
    "robots_in",
]
