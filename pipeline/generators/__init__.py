"""Generator families behind one interface (base.py); each family is a package here."""
