"""Files and pixels: OBJ, SMPL-format bodies, AMASS motions, USD stages, sequences, reports.

One format per module. Readers validate what they read and raise
`core.errors.InputError` naming the file, what was expected and what was found.
"""
