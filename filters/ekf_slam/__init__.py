"""World-centric EKF-SLAM baseline (``ekf-slam``), 2-D and 3-D in one design.

The classic filter (Smith, Self and Cheeseman; Dissanayake et al. 2001) that Bailey,
Nieto, Guivant, Stevens and Nebot (2006, "Consistency of the EKF-SLAM algorithm") showed
to become inconsistent: the Jacobians are evaluated at the current estimate, so the
linearised system has spurious heading information. Modules:

- ``config``: options (pydantic).
- ``layout``: the vehicle blocks of the joint state (the landmarks' places are the
  ``filters.state_registry.StateRegistry``'s, which the layout's blocks feed).
- ``motion``: vehicle motion models (odometry relative pose, gyro + constant velocity).
- ``motion_input``: the motion input chosen and one sample's increment or rate, motion gaps.
- ``observation``: body-frame landmark observation, its Jacobians and inverse.
- ``scan_update``: the map's predictions for association, the stacked scan update.
- ``landmarks``: landmark initialisation, sighting counts, probation.
- ``recording``: the recorded vehicle posterior, JCBB search diagnostics, the run's note.
- ``boundary``: conversion of the world-frame EKF error to the interface conventions.
- ``filter``: the estimator class ``EkfSlam``, which sequences the steps.
- ``multi_hypothesis``: ``ekf-slam-mht``, several ``EkfSlam`` under association hypotheses.

Kept free of imports so that loading one module does not load the others.
"""
