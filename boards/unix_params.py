"""Parameters of the simulated vehicle (boards/unix.py): a small quadcopter's set.

One row a parameter: (name, MAV_PARAM_TYPE, default, min, max, flags); see
docs/services/params.md. The table is what a ground station sees of a small
autopilot: every value can be listed, edited and kept; the simulator acts on the WP_*
speeds and radius, SIM_YAW_RATE, MIS_TAKEOFF_ALT, RTL_ALT, DISARM_DELAY, FS_GCS_ENABLE and FS_HOLD_S
(firmware/sim/), the rest are stored and served.
Integers are INT32, as on PX4: MAVSDK (4.x) lists and sets only INT32 and REAL32
parameters of a bytewise autopilot; the service itself takes every 8/16/32-bit type.
"""
from mavstack.services.params import INT32, REAL32, READ_ONLY, REBOOT

PARAMS = (
    # identity
    ("MAV_SYS_ID", INT32, 1, 1, 255, READ_ONLY),  # mirrors --sysid
    ("BRD_SERIAL_NUM", INT32, 0, 0, None, READ_ONLY),
    ("SYSID_MYGCS", INT32, 255, 1, 255),
    # simulation
    ("SIM_SPEED", REAL32, 5.0, 0.5, 30.0),
    ("SIM_CLIMB_RATE", REAL32, 2.5, 0.1, 10.0),
    ("SIM_SINK_RATE", REAL32, 1.5, 0.1, 10.0),
    ("SIM_YAW_RATE", REAL32, 90.0, 5.0, 360.0),
    ("SIM_ACCEL", REAL32, 3.0, 0.1, 20.0),
    ("SIM_WIND_SPD", REAL32, 0.0, 0.0, 20.0),
    ("SIM_WIND_DIR", REAL32, 180.0, 0.0, 360.0),
    ("SIM_GPS_NOISE", REAL32, 0.0, 0.0, 10.0),
    ("SIM_GPS_SATS", INT32, 12, 0, 40),
    ("SIM_GPS_GLITCH_M", REAL32, 0.0, 0.0, 100.0),  # 16 characters: no NUL on the wire
    ("SIM_BATT_VOLT", REAL32, 12.6, 6.0, 50.4),
    ("SIM_BATT_CELLS", INT32, 3, 1, 12),
    ("SIM_BATT_CAP_AH", REAL32, 5.0, 0.1, 100.0),
    ("SIM_DRAIN_A", REAL32, 12.0, 0.0, 200.0),
    ("SIM_SEED", INT32, 12345),
    ("SIM_RATE_HZ", INT32, 50, 10, 1000, REBOOT),
    # waypoint navigation
    ("WP_ACCEPT_RAD", REAL32, 2.0, 0.1, 100.0),
    ("WP_SPEED", REAL32, 5.0, 0.5, 30.0),
    ("WP_SPEED_UP", REAL32, 2.5, 0.1, 10.0),
    ("WP_SPEED_DN", REAL32, 1.5, 0.1, 10.0),
    ("WP_LOIT_RAD", REAL32, 10.0, 1.0, 500.0),
    ("WP_YAW_BEHAVIOR", INT32, 1, 0, 3),
    ("MIS_TAKEOFF_ALT", REAL32, 10.0, 1.0, 500.0),
    ("MIS_DIST_MAX", REAL32, 900.0, 0.0, 100000.0),
    ("MIS_AUTOCONT", INT32, 0, 0, 1),
    # return and landing
    ("RTL_ALT", REAL32, 15.0, 2.0, 300.0),  # m above home RTL returns at (or higher, if it is)
    ("RTL_SPEED", REAL32, 0.0, 0.0, 30.0),  # 0: WP_SPEED
    ("RTL_LOIT_TIME_S", REAL32, 5.0, 0.0, 300.0),  # 15 characters
    ("LAND_SPEED", REAL32, 0.5, 0.2, 5.0),
    ("LAND_SPEED_HIGH", REAL32, 1.5, 0.2, 5.0),
    ("LAND_ALT_LOW", REAL32, 10.0, 1.0, 100.0),
    ("DISARM_DELAY", INT32, 10, 0, 127),  # s armed on the ground, idle, before disarming (0: never)
    # battery and failsafes
    ("BATT_MONITOR", INT32, 4, 0, 20, REBOOT),
    ("BATT_CAPACITY", INT32, 5000, 0, 1000000),
    ("BATT_LOW_VOLT", REAL32, 10.5, 0.0, 60.0),
    ("BATT_CRT_VOLT", REAL32, 10.0, 0.0, 60.0),
    ("BATT_LOW_MAH", INT32, 800, 0, 1000000),
    ("BATT_CRT_MAH", INT32, 300, 0, 1000000),
    ("BATT_LOW_TIMER", INT32, 10, 0, 120),
    ("BATT_FS_LOW_ACT", INT32, 2, 0, 5),
    ("BATT_FS_CRT_ACT", INT32, 1, 0, 5),
    ("BATT_ARM_VOLT", REAL32, 0.0, 0.0, 60.0),
    ("FS_GCS_ENABLE", INT32, 1, 0, 5),
    ("FS_GCS_TIMEOUT", REAL32, 5.0, 1.0, 120.0),
    ("FS_HOLD_S", REAL32, 5.0, 0.0, 120.0),  # a failsafe holds this long, then returns
    ("FS_THR_ENABLE", INT32, 0, 0, 5),
    ("FS_EKF_THRESH", REAL32, 0.8, 0.0, 1.0),
    ("FS_CRASH_CHECK", INT32, 1, 0, 1),
    ("FS_OPTIONS", INT32, 0, 0, None),
    # geofence
    ("FENCE_ENABLE", INT32, 0, 0, 1),
    ("FENCE_TYPE", INT32, 7, 0, 15),
    ("FENCE_ACTION", INT32, 1, 0, 5),
    ("FENCE_ALT_MAX", REAL32, 100.0, 10.0, 1000.0),
    ("FENCE_RADIUS", REAL32, 300.0, 30.0, 10000.0),
    ("FENCE_MARGIN", REAL32, 2.0, 1.0, 10.0),
    # arming
    ("ARMING_CHECK", INT32, 1, 0, None),
    ("ARMING_REQUIRE", INT32, 1, 0, 2),
    ("ARMING_ACCTHRESH", REAL32, 0.75, 0.25, 3.0),
    # attitude control
    ("ATC_RAT_RLL_P", REAL32, 0.135, 0.0, 0.5),
    ("ATC_RAT_RLL_I", REAL32, 0.135, 0.0, 2.0),
    ("ATC_RAT_RLL_D", REAL32, 0.0036, 0.0, 0.05),
    ("ATC_RAT_PIT_P", REAL32, 0.135, 0.0, 0.5),
    ("ATC_RAT_PIT_I", REAL32, 0.135, 0.0, 2.0),
    ("ATC_RAT_PIT_D", REAL32, 0.0036, 0.0, 0.05),
    ("ATC_RAT_YAW_P", REAL32, 0.18, 0.0, 2.5),
    ("ATC_RAT_YAW_I", REAL32, 0.018, 0.0, 1.0),
    ("ATC_ANG_RLL_P", REAL32, 4.5, 3.0, 12.0),
    ("ATC_ANG_PIT_P", REAL32, 4.5, 3.0, 12.0),
    ("ATC_ANG_YAW_P", REAL32, 4.5, 3.0, 12.0),
    ("ATC_ACCEL_R_MAX", REAL32, 110000.0, 0.0, 180000.0),
    ("ATC_ACCEL_Y_MAX", REAL32, 27000.0, 0.0, 72000.0),
    # position control
    ("PSC_POSXY_P", REAL32, 1.0, 0.5, 2.0),
    ("PSC_VELXY_P", REAL32, 2.0, 0.1, 6.0),
    ("PSC_POSZ_P", REAL32, 1.0, 1.0, 3.0),
    ("PSC_VELZ_P", REAL32, 5.0, 1.0, 8.0),
    ("ANGLE_MAX", INT32, 3000, 1000, 8000),  # centidegrees
    ("PILOT_SPEED_UP", REAL32, 2.5, 0.5, 5.0),
    ("PILOT_Y_RATE", REAL32, 202.5, 1.0, 500.0),
    # motors
    ("MOT_SPIN_ARM", REAL32, 0.1, 0.0, 0.2),
    ("MOT_SPIN_MIN", REAL32, 0.15, 0.0, 0.3),
    ("MOT_THST_HOVER", REAL32, 0.35, 0.125, 0.6875),
    ("MOT_PWM_MIN", INT32, 1000, 0, 2000),
    ("MOT_PWM_MAX", INT32, 2000, 0, 2200),
    ("MOT_SPOOL_TIME_S", REAL32, 0.5, 0.0, 2.0),  # 16 characters
    # flight modes (MAV_MODE custom modes on a generic autopilot)
    ("FLTMODE_CH", INT32, 5, -1, 16),
    ("FLTMODE1", INT32, 0, 0, 255),
    ("FLTMODE2", INT32, 0, 0, 255),
    # sensors and links
    ("GPS_TYPE", INT32, 1, 0, 20, REBOOT),
    ("GPS_HDOP_GOOD", INT32, 140, 100, 900),
    ("COMPASS_DEC", REAL32, 0.0, -3.142, 3.142),
    ("INS_GYRO_FILTER", INT32, 20, 0, 256),
    ("SERIAL1_BAUD", INT32, 57600, 1200, 921600, REBOOT),
    ("LOG_BITMASK", INT32, 176126, 0, None),
    # telemetry rates in Hz, per link
    ("SIM_MASS_KG", REAL32, 1.5, 0.1, 50.0),
    ("SIM_DRAG", REAL32, 0.2, 0.0, 5.0),
    ("SIM_TEMP_C", REAL32, 20.0, -40.0, 60.0),
    ("SIM_BARO_NOISE", REAL32, 0.1, 0.0, 10.0),
    ("SIM_MAG_NOISE", REAL32, 0.0, 0.0, 10.0),
)
