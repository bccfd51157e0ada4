"""The console scripts of pam_controller (setup.py), quiet on a stop during start-up
(pam_model.cli.startup: the nodes keep the quiet handlers until they install their own)."""

from pam_model.cli.startup import entry

pi_node = entry('pam_controller.pi_node:main', own_handlers=True)
reference_node = entry('pam_controller.reference_node:main', own_handlers=True)
profile_player = entry('pam_controller.profile_player:main', own_handlers=True)
pam_robustness = entry('pam_controller.robustness_cli:main')
