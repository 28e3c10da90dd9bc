"""Contact detection: hair-body and hair-hair contacts of fitted strands (the ``/contacts`` group).

``detect_contacts(helices, body, settings)`` returns the declared
:class:`Contacts` and a :class:`DetectReport`; the rules are in
docs/contacts.md.
"""

from .body import BodyMesh
from .detect import BODY, Contacts, DetectReport, contact_frames, detect_contacts, validate_settings

__all__ = ["BODY", "BodyMesh", "Contacts", "DetectReport", "contact_frames", "detect_contacts", "validate_settings"]
