"""R-SLAM dense radar SLAM (seed 1 §4.1) and the dead-reckoning baseline."""

from .dead_reckoning import DeadReckoning
from .matching import MatchParams, MatchResult, match_to_map
from .rslam import RSlam, RSlamConfig, RSlamCore
from .tilemap import TileMap

__all__ = ["RSlam", "RSlamCore", "RSlamConfig", "DeadReckoning", "MatchParams", "MatchResult", "match_to_map",
           "TileMap"]
