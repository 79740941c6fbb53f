"""Face meshes: topology, holes and regions, closest points, marker binding."""
from ..model.mesh import Binding, FaceMesh, Region

__all__ = ["Binding", "FaceMesh", "Region"]
