"""Offline studies: training the gait model, leave-one-subject-out cross-validation, the replay
command and the speed benchmark."""
