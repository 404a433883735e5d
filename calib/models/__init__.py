"""Camera models, one module each. Importing this package registers all of them."""

from .double_sphere import DoubleSphere
from .enhanced_unified import EnhancedUnified
from .fisheye624 import Fisheye624
from .kannala_brandt import KannalaBrandt
from .pinhole import Pinhole
from .radial_poly import RadialPoly
from .unified import Unified

__all__ = ["DoubleSphere", "EnhancedUnified", "Fisheye624", "KannalaBrandt", "Pinhole", "RadialPoly",
           "Unified"]
