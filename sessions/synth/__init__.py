"""The virtual cohort: normative gait data, synthetic subjects and their walks, and simulated sensors."""
