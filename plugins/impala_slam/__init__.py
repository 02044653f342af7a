"""R-SLAM dense radar SLAM (seed 1 §4.1) and the dead-reckoning baseline."""
