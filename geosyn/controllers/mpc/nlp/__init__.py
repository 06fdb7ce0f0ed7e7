"""The interior-point solver family (fatrop, IPOPT): the tracking OCP transcribed as one
multiple-shooting NLP, behind `geosyn.controllers.mpc.backend.TrackingBackend`."""

from geosyn.controllers.mpc.nlp.options import NLPOptions
from geosyn.controllers.mpc.nlp.tracking import NLPTracking, nlp_backend

__all__ = ["NLPOptions", "NLPTracking", "nlp_backend"]
