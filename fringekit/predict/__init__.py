"""Predict: config -> mesh -> contact solution -> fringe maps and camera images."""

from fringekit.predict.pipeline import Prediction, PredictError, PredictInterrupted, predict

__all__ = ["PredictError", "PredictInterrupted", "Prediction", "predict"]
