"""The console scripts of pam_estimator (setup.py), quiet on a stop during start-up
(pam_model.cli.startup: the node keeps the quiet handlers until run_node installs its own)."""

from pam_model.cli.startup import entry

ukf_node = entry('pam_estimator.ukf_node:main', own_handlers=True)
pam_evaluate = entry('pam_estimator.cli.evaluate:main')
pam_identify = entry('pam_estimator.cli.identify:main')
pam_calibration_bags = entry('pam_estimator.cli.calibration_bags:main')
