"""Learning from a heuristic teacher: the clone before RL (clone.py), the teacher term inside PPO's loss
(teacher_term.py) and the wrapper that labels the learner's own states with the teacher's actions
(teacher_labels.py). Parts of the training algorithm, above the controllers and policies they use and below the
training app that chooses them (searchrl/train/)."""
