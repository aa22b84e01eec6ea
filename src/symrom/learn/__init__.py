"""Learning a symbolic model from data: the estimator, encoders, regressors, training and fine-tuning."""
