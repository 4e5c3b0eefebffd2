"""What a labelled map's POC regions are used for: paths of POC poses
between two poses (:mod:`~cdpm.regions.paths`, on the graphs of
:mod:`~cdpm.regions.graph`; on a certified map, paths through certified
boxes, :mod:`~cdpm.regions.certified`), the POC neighbourhood of one pose
and its certified box (:mod:`~cdpm.regions.neighbourhood`) and a random search for poses worth
analysing (:mod:`~cdpm.regions.search`, ``cdpm find``). A map's regions themselves are labelled
with the map (:mod:`cdpm.maps.regions`): the store keeps them.
"""

from cdpm.regions.certified import CertifiedPath, certified_path
from cdpm.regions.neighbourhood import (
    CertifiedNeighbourhood,
    Neighbourhood,
    certified_neighbourhood,
    poc_neighbourhood,
)
from cdpm.regions.paths import NotConnectedError, POCPath, poc_path
from cdpm.regions.search import FoundPose, PoseSearch, SearchBox, find_poses, search_box

__all__ = [
    "Neighbourhood",
    "poc_neighbourhood",
    "CertifiedNeighbourhood",
    "certified_neighbourhood",
    "CertifiedPath",
    "certified_path",
    "NotConnectedError",
    "POCPath",
    "poc_path",
    "find_poses",
    "search_box",
    "PoseSearch",
    "SearchBox",
    "FoundPose",
]
