"""Writers of the robot models in other tools' formats."""
