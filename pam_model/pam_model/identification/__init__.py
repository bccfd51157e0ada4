"""Parameter identification from calibration runs (pam-identify), without ROS.

MODEL.md sections 3-4 and Proposition 1 of the paper: A1, A2, k1, k2 shape transients, mu_p and
mu_s steady states, the force coefficients come from static data, kappa(u) from static holds.
The fits, in the paper's order except that kappa comes before the transients it drives (it does
not depend on A_0 or k1, Prop. 1); each reads the runs it can use:

  forces     p_v1, p_v2 of each muscle and the two identifiable intercept combinations, from the
             torque meter of locked runs at two or more angles (linear least squares);
  friction   mu_s and mu_p, from the angle of free runs driven by their measured pressures
             (output error through Kikuuwe's friction; needs the forces);
  valve_map  kappa(u) from the settled static holds of locked runs (section 4 procedure);
  flow       the effective valve areas A1, A2 of each valve (with k1 held: eq. (4)-(5) see only
             the product k1 A_0) and k2, from the pressure transients (output error; needs kappa).

Modules: records (a run as the fits read it), fit_result (estimates, uncertainties), valve_fit,
force_fit, flow_fit, friction_fit, identify (the whole procedure and its report).
"""
