"""Contact detection: hair-body and hair-hair contacts of fitted strands (the ``/contacts`` group).

``detect_contacts(helices, body, settings)`` returns the declared
:class:`~hairinv.model.Contacts` and a :class:`DetectReport`; the rules are in
docs/contacts.md.
"""

from .body import BodyMesh
from .detect import DetectReport, contact_frames, detect_contacts, validate_settings

__all__ = ["BodyMesh", "DetectReport", "contact_frames", "detect_contacts", "validate_settings"]
