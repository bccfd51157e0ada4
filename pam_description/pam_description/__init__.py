"""pam_description: the URDF of the antagonistic PAM joint (urdf/pam_joint.urdf, installed under
share/pam_description/urdf/). Data only: this package imports nothing and holds no code."""
