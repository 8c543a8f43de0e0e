"""Online estimation of what the relay is not told (the jammers: ``jammer_estimator``)."""
