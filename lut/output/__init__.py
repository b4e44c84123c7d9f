"""What a person looks at.

The plan file (JSON/CSV), its figures, the 3D preview, a table's coverage maps, output path checks.
"""
