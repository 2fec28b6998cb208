"""The hand-written equation modules that the shipped energy-first ones replaced (issue 47):
the independent references the tests compare the derived modules with. Loaded as any user
module (``load_problem(REFERENCE / "kirchhoff_lever_arm.py")``) or imported
(``import reference.kirchhoff_lever_arm``); not shipped."""
