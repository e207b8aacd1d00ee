"""A library calibrated to one physical sensor (``fringekit sensor calibrate``): the
sheet's modulus and fringe value, the camera's response and black level, the light, the
sheet at rest and where the sheet lies in the image, from rest frames and a few frames of
known loads (:func:`calibrate_sensor`); the file it writes is read by ``invert`` and
``track`` (:class:`~fringekit.library.calibrated.CalibratedSensor`)."""

from fringekit.library.calibrated import CalibratedSensor, load_sensor
from fringekit.sensor.calibrate import SensorCalibration, calibrate_sensor
from fringekit.sensor.render import sensor_frame

__all__ = [
    "CalibratedSensor",
    "SensorCalibration",
    "calibrate_sensor",
    "load_sensor",
    "sensor_frame",
]
