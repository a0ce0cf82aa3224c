"""PPO (stable-baselines3) on the tuning environment: the policy, its reward, callbacks, hyper-parameter search, recommendation and refinement."""
