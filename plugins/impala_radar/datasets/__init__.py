"""Readers of the public spinning-radar datasets (Navtech): Oxford Radar RobotCar, Boreas, RADIATE.

Each reader turns a dataset folder into what a live radar would give: :class:`~impala_msgs.RadarBeam`
messages in acquisition order, each with its own timestamp (int ns) and its azimuth in the
project convention (vehicle frame, 0 = forward, counter-clockwise positive, wrapped), plus the
dataset's ground truth as :class:`~impala_flow.msgs.Pose2D` (x forward, y left, yaw CCW).
The sensor's numbers (bins, range per bin, range of bin 0, beams per turn, rotation rate)
come from the dataset and travel in every beam's :class:`~impala_msgs.RadarConfig`.

Bad input raises :class:`DatasetError`: one line naming the file and the row or scan. Options are
checked in the constructors (finite, physically possible: :func:`.common.check_option`); every value
read is checked where it is read (Unix times, row times against the scan names, truth steps and GPS
fields within what a vehicle and the Earth allow, the turn rate against the Navtech's 4 Hz, the
mission's span and clock steps back): no NaN or inf leaves a reader.
"""
