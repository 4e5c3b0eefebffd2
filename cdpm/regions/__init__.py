"""What a labelled map's POC regions are used for: paths of POC poses
between two poses (:mod:`~cdpm.regions.paths`, on the graphs of
:mod:`~cdpm.regions.graph`) and the POC neighbourhood of one pose
(:mod:`~cdpm.regions.neighbourhood`). A map's regions themselves are labelled
with the map (:mod:`cdpm.maps.regions`): the store keeps them.
"""

from cdpm.regions.neighbourhood import Neighbourhood, poc_neighbourhood
from cdpm.regions.paths import NotConnectedError, POCPath, poc_path

__all__ = ["Neighbourhood", "poc_neighbourhood", "NotConnectedError", "POCPath", "poc_path"]
