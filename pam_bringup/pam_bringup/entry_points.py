"""The console scripts of pam_bringup (setup.py), quiet on a stop during start-up
(pam_model.cli.startup: pam-bringup, tracking_report and pam-demo keep the quiet handlers
until they install their own)."""

from pam_model.cli.startup import entry

pam_bringup = entry('pam_bringup.bringup:main', own_handlers=True)
tracking_report = entry('pam_bringup.tracking_report:main', own_handlers=True)
pam_demo = entry('pam_bringup.demo:main', own_handlers=True)
pam_foxglove = entry('pam_bringup.foxglove_view:main', own_handlers=True)
pam_container = entry('pam_bringup.container:main', own_handlers=True)
