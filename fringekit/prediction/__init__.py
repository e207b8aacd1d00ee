"""Predict: config -> mesh -> contact solution -> fringe maps and camera images."""

from fringekit.prediction.pipeline import PredictError, PredictInterrupted, Prediction, predict

__all__ = ["PredictError", "PredictInterrupted", "Prediction", "predict"]
