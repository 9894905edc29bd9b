"""Contacts, stepping phase and features of gait windows, and the validation of foot events against annotated C3D
trials."""
