"""Pictures: annotated photos, debug stages, the study's and the evaluation's plots.

The only sub-package that imports matplotlib, and only inside the functions that draw.
"""
