"""Control laws of the ground robots: the car's bicycle kinematics and its go-to task (``car_goto``), the
unicycle go-to task of the Husky (``unicycle_goto``). numpy and the public framework API only."""
