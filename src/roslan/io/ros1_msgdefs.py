# ruff: noqa: E501
"""ROS 1 message definition texts as ROS 1 ships them (comments and blank lines kept).

ROS 1 bags store, per connection, the "full text" that genmsg's gendeps builds from these
``.msg`` files: the type's own text, then for each dependency (depth first, in field
order, each once) a line of 80 ``=``, ``MSG: pkg/Type`` and that type's text.
``rosbag check`` compares that text with the installed definitions, so a stripped
definition (same md5 sum) is reported as needing a migration. Texts below are the
public ROS 1 Noetic definitions (std_msgs, geometry_msgs, sensor_msgs, nav_msgs,
tf2_msgs, visualization_msgs in :mod:`roslan.io.ros1_visualization_msgdefs`, vision_msgs
in :mod:`roslan.io.vision_msgdefs`) and
rpg_dvs_ros' dvs_msgs; md5 sums are still computed by rosbags from the
fields, and tests check both against Debian's ROS 1 packages where installed.
"""

from __future__ import annotations

from roslan.io.ros1_visualization_msgdefs import VISUALIZATION_MSG_TEXTS
from roslan.io.vision_msgdefs import ROS1_VISION_MSG_TEXTS

__all__ = ["ROS1_MSG_TEXTS", "ros1_full_text"]

ROS1_MSG_TEXTS: dict[str, str] = {
    "dvs_msgs/Event": ("# A DVS event\nuint16 x\nuint16 y\ntime ts\nbool polarity\n"),
    "dvs_msgs/EventArray": (
        "# This message contains an array of events\n"
        "# (0, 0) is at top-left corner of image\n"
        "#\n"
        "\n"
        "Header header\n"
        "\n"
        "uint32 height         # image height, that is, number of rows\n"
        "uint32 width          # image width, that is, number of columns\n"
        "\n"
        "# an array of events\n"
        "Event[] events\n"
    ),
    "geometry_msgs/Accel": (
        "# This expresses acceleration in free space broken into its linear and angular parts.\n"
        "Vector3  linear\n"
        "Vector3  angular\n"
    ),
    "geometry_msgs/AccelStamped": (
        "# An accel with reference coordinate frame and timestamp\nHeader header\nAccel accel\n"
    ),
    "geometry_msgs/Point": (
        "# This contains the position of a point in free space\nfloat64 x\nfloat64 y\nfloat64 z\n"
    ),
    "geometry_msgs/Pose": (
        "# A representation of pose in free space, composed of position and orientation. \n"
        "Point position\n"
        "Quaternion orientation\n"
    ),
    "geometry_msgs/PoseStamped": (
        "# A Pose with reference coordinate frame and timestamp\nHeader header\nPose pose\n"
    ),
    "geometry_msgs/PoseWithCovariance": (
        "# This represents a pose in free space with uncertainty.\n"
        "\n"
        "Pose pose\n"
        "\n"
        "# Row-major representation of the 6x6 covariance matrix\n"
        "# The orientation parameters use a fixed-axis representation.\n"
        "# In order, the parameters are:\n"
        "# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)\n"
        "float64[36] covariance\n"
    ),
    "geometry_msgs/Quaternion": (
        "# This represents an orientation in free space in quaternion form.\n"
        "\n"
        "float64 x\n"
        "float64 y\n"
        "float64 z\n"
        "float64 w\n"
    ),
    "geometry_msgs/Transform": (
        "# This represents the transform between two coordinate frames in free space.\n"
        "\n"
        "Vector3 translation\n"
        "Quaternion rotation\n"
    ),
    "geometry_msgs/TransformStamped": (
        "# This expresses a transform from coordinate frame header.frame_id\n"
        "# to the coordinate frame child_frame_id\n"
        "#\n"
        "# This message is mostly used by the \n"
        '# <a href="http://wiki.ros.org/tf">tf</a> package. \n'
        "# See its documentation for more information.\n"
        "\n"
        "Header header\n"
        "string child_frame_id # the frame id of the child frame\n"
        "Transform transform\n"
    ),
    "geometry_msgs/Twist": (
        "# This expresses velocity in free space broken into its linear and angular parts.\n"
        "Vector3  linear\n"
        "Vector3  angular\n"
    ),
    "geometry_msgs/TwistWithCovariance": (
        "# This expresses velocity in free space with uncertainty.\n"
        "\n"
        "Twist twist\n"
        "\n"
        "# Row-major representation of the 6x6 covariance matrix\n"
        "# The orientation parameters use a fixed-axis representation.\n"
        "# In order, the parameters are:\n"
        "# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)\n"
        "float64[36] covariance\n"
    ),
    "geometry_msgs/Vector3": (
        "# This represents a vector in free space. \n"
        "# It is only meant to represent a direction. Therefore, it does not\n"
        "# make sense to apply a translation to it (e.g., when applying a \n"
        "# generic rigid transformation to a Vector3, tf2 will only apply the\n"
        "# rotation). If you want your data to be translatable too, use the\n"
        "# geometry_msgs/Point message instead.\n"
        "\n"
        "float64 x\n"
        "float64 y\n"
        "float64 z"
    ),
    "nav_msgs/Odometry": (
        "# This represents an estimate of a position and velocity in free space.  \n"
        "# The pose in this message should be specified in the coordinate frame given by header.frame_id.\n"
        "# The twist in this message should be specified in the coordinate frame given by the child_frame_id\n"
        "Header header\n"
        "string child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist\n"
    ),
    "sensor_msgs/CameraInfo": (
        "# This message defines meta information for a camera. It should be in a\n"
        '# camera namespace on topic "camera_info" and accompanied by up to five\n'
        "# image topics named:\n"
        "#\n"
        "#   image_raw - raw data from the camera driver, possibly Bayer encoded\n"
        "#   image            - monochrome, distorted\n"
        "#   image_color      - color, distorted\n"
        "#   image_rect       - monochrome, rectified\n"
        "#   image_rect_color - color, rectified\n"
        "#\n"
        "# The image_pipeline contains packages (image_proc, stereo_image_proc)\n"
        "# for producing the four processed image topics from image_raw and\n"
        "# camera_info. The meaning of the camera parameters are described in\n"
        "# detail at http://www.ros.org/wiki/image_pipeline/CameraInfo.\n"
        "#\n"
        "# The image_geometry package provides a user-friendly interface to\n"
        "# common operations using this meta information. If you want to, e.g.,\n"
        "# project a 3d point into image coordinates, we strongly recommend\n"
        "# using image_geometry.\n"
        "#\n"
        "# If the camera is uncalibrated, the matrices D, K, R, P should be left\n"
        "# zeroed out. In particular, clients may assume that K[0] == 0.0\n"
        "# indicates an uncalibrated camera.\n"
        "\n"
        "#######################################################################\n"
        "#                     Image acquisition info                          #\n"
        "#######################################################################\n"
        "\n"
        "# Time of image acquisition, camera coordinate frame ID\n"
        "Header header    # Header timestamp should be acquisition time of image\n"
        "                 # Header frame_id should be optical frame of camera\n"
        "                 # origin of frame should be optical center of camera\n"
        "                 # +x should point to the right in the image\n"
        "                 # +y should point down in the image\n"
        "                 # +z should point into the plane of the image\n"
        "\n"
        "\n"
        "#######################################################################\n"
        "#                      Calibration Parameters                         #\n"
        "#######################################################################\n"
        "# These are fixed during camera calibration. Their values will be the #\n"
        "# same in all messages until the camera is recalibrated. Note that    #\n"
        '# self-calibrating systems may "recalibrate" frequently.              #\n'
        "#                                                                     #\n"
        "# The internal parameters can be used to warp a raw (distorted) image #\n"
        "# to:                                                                 #\n"
        "#   1. An undistorted image (requires D and K)                        #\n"
        "#   2. A rectified image (requires D, K, R)                           #\n"
        "# The projection matrix P projects 3D points into the rectified image.#\n"
        "#######################################################################\n"
        "\n"
        "# The image dimensions with which the camera was calibrated. Normally\n"
        "# this will be the full camera resolution in pixels.\n"
        "uint32 height\n"
        "uint32 width\n"
        "\n"
        "# The distortion model used. Supported models are listed in\n"
        '# sensor_msgs/distortion_models.h. For most cameras, "plumb_bob" - a\n'
        "# simple model of radial and tangential distortion - is sufficient.\n"
        "string distortion_model\n"
        "\n"
        "# The distortion parameters, size depending on the distortion model.\n"
        '# For "plumb_bob", the 5 parameters are: (k1, k2, t1, t2, k3).\n'
        "float64[] D\n"
        "\n"
        "# Intrinsic camera matrix for the raw (distorted) images.\n"
        "#     [fx  0 cx]\n"
        "# K = [ 0 fy cy]\n"
        "#     [ 0  0  1]\n"
        "# Projects 3D points in the camera coordinate frame to 2D pixel\n"
        "# coordinates using the focal lengths (fx, fy) and principal point\n"
        "# (cx, cy).\n"
        "float64[9]  K # 3x3 row-major matrix\n"
        "\n"
        "# Rectification matrix (stereo cameras only)\n"
        "# A rotation matrix aligning the camera coordinate system to the ideal\n"
        "# stereo image plane so that epipolar lines in both stereo images are\n"
        "# parallel.\n"
        "float64[9]  R # 3x3 row-major matrix\n"
        "\n"
        "# Projection/camera matrix\n"
        "#     [fx'  0  cx' Tx]\n"
        "# P = [ 0  fy' cy' Ty]\n"
        "#     [ 0   0   1   0]\n"
        "# By convention, this matrix specifies the intrinsic (camera) matrix\n"
        "#  of the processed (rectified) image. That is, the left 3x3 portion\n"
        "#  is the normal camera intrinsic matrix for the rectified image.\n"
        "# It projects 3D points in the camera coordinate frame to 2D pixel\n"
        "#  coordinates using the focal lengths (fx', fy') and principal point\n"
        "#  (cx', cy') - these may differ from the values in K.\n"
        "# For monocular cameras, Tx = Ty = 0. Normally, monocular cameras will\n"
        "#  also have R = the identity and P[1:3,1:3] = K.\n"
        "# For a stereo pair, the fourth column [Tx Ty 0]' is related to the\n"
        "#  position of the optical center of the second camera in the first\n"
        "#  camera's frame. We assume Tz = 0 so both cameras are in the same\n"
        "#  stereo image plane. The first camera always has Tx = Ty = 0. For\n"
        "#  the right (second) camera of a horizontal stereo pair, Ty = 0 and\n"
        "#  Tx = -fx' * B, where B is the baseline between the cameras.\n"
        "# Given a 3D point [X Y Z]', the projection (x, y) of the point onto\n"
        "#  the rectified image is given by:\n"
        "#  [u v w]' = P * [X Y Z 1]'\n"
        "#         x = u / w\n"
        "#         y = v / w\n"
        "#  This holds for both images of a stereo pair.\n"
        "float64[12] P # 3x4 row-major matrix\n"
        "\n"
        "\n"
        "#######################################################################\n"
        "#                      Operational Parameters                         #\n"
        "#######################################################################\n"
        "# These define the image region actually captured by the camera       #\n"
        "# driver. Although they affect the geometry of the output image, they #\n"
        "# may be changed freely without recalibrating the camera.             #\n"
        "#######################################################################\n"
        "\n"
        "# Binning refers here to any camera setting which combines rectangular\n"
        '#  neighborhoods of pixels into larger "super-pixels." It reduces the\n'
        "#  resolution of the output image to\n"
        "#  (width / binning_x) x (height / binning_y).\n"
        "# The default values binning_x = binning_y = 0 is considered the same\n"
        "#  as binning_x = binning_y = 1 (no subsampling).\n"
        "uint32 binning_x\n"
        "uint32 binning_y\n"
        "\n"
        "# Region of interest (subwindow of full camera resolution), given in\n"
        "#  full resolution (unbinned) image coordinates. A particular ROI\n"
        "#  always denotes the same window of pixels on the camera sensor,\n"
        "#  regardless of binning settings.\n"
        "# The default setting of roi (all values 0) is considered the same as\n"
        "#  full resolution (roi.width = width, roi.height = height).\n"
        "RegionOfInterest roi\n"
    ),
    "sensor_msgs/CompressedImage": (
        "# This message contains a compressed image\n"
        "\n"
        "Header header        # Header timestamp should be acquisition time of image\n"
        "                     # Header frame_id should be optical frame of camera\n"
        "                     # origin of frame should be optical center of camera\n"
        "                     # +x should point to the right in the image\n"
        "                     # +y should point down in the image\n"
        "                     # +z should point into to plane of the image\n"
        "\n"
        "string format        # Specifies the format of the data\n"
        "                     #   Acceptable values:\n"
        "                     #     jpeg, png\n"
        "uint8[] data         # Compressed image buffer\n"
    ),
    "sensor_msgs/Image": (
        "# This message contains an uncompressed image\n"
        "# (0, 0) is at top-left corner of image\n"
        "#\n"
        "\n"
        "Header header        # Header timestamp should be acquisition time of image\n"
        "                     # Header frame_id should be optical frame of camera\n"
        "                     # origin of frame should be optical center of camera\n"
        "                     # +x should point to the right in the image\n"
        "                     # +y should point down in the image\n"
        "                     # +z should point into to plane of the image\n"
        "                     # If the frame_id here and the frame_id of the CameraInfo\n"
        "                     # message associated with the image conflict\n"
        "                     # the behavior is undefined\n"
        "\n"
        "uint32 height         # image height, that is, number of rows\n"
        "uint32 width          # image width, that is, number of columns\n"
        "\n"
        "# The legal values for encoding are in file src/image_encodings.cpp\n"
        "# If you want to standardize a new string format, join\n"
        "# ros-users@lists.sourceforge.net and send an email proposing a new encoding.\n"
        "\n"
        "string encoding       # Encoding of pixels -- channel meaning, ordering, size\n"
        "                      # taken from the list of strings in include/sensor_msgs/image_encodings.h\n"
        "\n"
        "uint8 is_bigendian    # is this data bigendian?\n"
        "uint32 step           # Full row length in bytes\n"
        "uint8[] data          # actual matrix data, size is (step * rows)\n"
    ),
    "sensor_msgs/Imu": (
        "# This is a message to hold data from an IMU (Inertial Measurement Unit)\n"
        "#\n"
        "# Accelerations should be in m/s^2 (not in g's), and rotational velocity should be in rad/sec\n"
        "#\n"
        "# If the covariance of the measurement is known, it should be filled in (if all you know is the \n"
        "# variance of each measurement, e.g. from the datasheet, just put those along the diagonal)\n"
        '# A covariance matrix of all zeros will be interpreted as "covariance unknown", and to use the\n'
        "# data a covariance will have to be assumed or gotten from some other source\n"
        "#\n"
        "# If you have no estimate for one of the data elements (e.g. your IMU doesn't produce an orientation \n"
        "# estimate), please set element 0 of the associated covariance matrix to -1\n"
        "# If you are interpreting this message, please check for a value of -1 in the first element of each \n"
        "# covariance matrix, and disregard the associated estimate.\n"
        "\n"
        "Header header\n"
        "\n"
        "geometry_msgs/Quaternion orientation\n"
        "float64[9] orientation_covariance # Row major about x, y, z axes\n"
        "\n"
        "geometry_msgs/Vector3 angular_velocity\n"
        "float64[9] angular_velocity_covariance # Row major about x, y, z axes\n"
        "\n"
        "geometry_msgs/Vector3 linear_acceleration\n"
        "float64[9] linear_acceleration_covariance # Row major x, y z \n"
    ),
    "sensor_msgs/LaserScan": (
        "# Single scan from a planar laser range-finder\n"
        "#\n"
        "# If you have another ranging device with different behavior (e.g. a sonar\n"
        "# array), please find or create a different message, since applications\n"
        "# will make fairly laser-specific assumptions about this data\n"
        "\n"
        "Header header            # timestamp in the header is the acquisition time of \n"
        "                         # the first ray in the scan.\n"
        "                         #\n"
        "                         # in frame frame_id, angles are measured around \n"
        "                         # the positive Z axis (counterclockwise, if Z is up)\n"
        "                         # with zero angle being forward along the x axis\n"
        "                         \n"
        "float32 angle_min        # start angle of the scan [rad]\n"
        "float32 angle_max        # end angle of the scan [rad]\n"
        "float32 angle_increment  # angular distance between measurements [rad]\n"
        "\n"
        "float32 time_increment   # time between measurements [seconds] - if your scanner\n"
        "                         # is moving, this will be used in interpolating position\n"
        "                         # of 3d points\n"
        "float32 scan_time        # time between scans [seconds]\n"
        "\n"
        "float32 range_min        # minimum range value [m]\n"
        "float32 range_max        # maximum range value [m]\n"
        "\n"
        "float32[] ranges         # range data [m] (Note: values < range_min or > range_max should be discarded)\n"
        "float32[] intensities    # intensity data [device-specific units].  If your\n"
        "                         # device does not provide intensities, please leave\n"
        "                         # the array empty.\n"
    ),
    "sensor_msgs/PointCloud2": (
        "# This message holds a collection of N-dimensional points, which may\n"
        "# contain additional information such as normals, intensity, etc. The\n"
        "# point data is stored as a binary blob, its layout described by the\n"
        '# contents of the "fields" array.\n'
        "\n"
        "# The point cloud data may be organized 2d (image-like) or 1d\n"
        "# (unordered). Point clouds organized as 2d images may be produced by\n"
        "# camera depth sensors such as stereo or time-of-flight.\n"
        "\n"
        "# Time of sensor data acquisition, and the coordinate frame ID (for 3d\n"
        "# points).\n"
        "Header header\n"
        "\n"
        "# 2D structure of the point cloud. If the cloud is unordered, height is\n"
        "# 1 and width is the length of the point cloud.\n"
        "uint32 height\n"
        "uint32 width\n"
        "\n"
        "# Describes the channels and their layout in the binary data blob.\n"
        "PointField[] fields\n"
        "\n"
        "bool    is_bigendian # Is this data bigendian?\n"
        "uint32  point_step   # Length of a point in bytes\n"
        "uint32  row_step     # Length of a row in bytes\n"
        "uint8[] data         # Actual point data, size is (row_step*height)\n"
        "\n"
        "bool is_dense        # True if there are no invalid points\n"
    ),
    "sensor_msgs/PointField": (
        "# This message holds the description of one point entry in the\n"
        "# PointCloud2 message format.\n"
        "uint8 INT8    = 1\n"
        "uint8 UINT8   = 2\n"
        "uint8 INT16   = 3\n"
        "uint8 UINT16  = 4\n"
        "uint8 INT32   = 5\n"
        "uint8 UINT32  = 6\n"
        "uint8 FLOAT32 = 7\n"
        "uint8 FLOAT64 = 8\n"
        "\n"
        "string name      # Name of field\n"
        "uint32 offset    # Offset from start of point struct\n"
        "uint8  datatype  # Datatype enumeration, see above\n"
        "uint32 count     # How many elements in the field\n"
    ),
    "sensor_msgs/Range": (
        "# Single range reading from an active ranger that emits energy and reports\n"
        "# one range reading that is valid along an arc at the distance measured. \n"
        "# This message is  not appropriate for laser scanners. See the LaserScan\n"
        "# message if you are working with a laser scanner.\n"
        "\n"
        "# This message also can represent a fixed-distance (binary) ranger.  This\n"
        "# sensor will have min_range===max_range===distance of detection.\n"
        "# These sensors follow REP 117 and will output -Inf if the object is detected\n"
        "# and +Inf if the object is outside of the detection range.\n"
        "\n"
        "Header header           # timestamp in the header is the time the ranger\n"
        "                        # returned the distance reading\n"
        "\n"
        "# Radiation type enums\n"
        "# If you want a value added to this list, send an email to the ros-users list\n"
        "uint8 ULTRASOUND=0\n"
        "uint8 INFRARED=1\n"
        "\n"
        "uint8 radiation_type    # the type of radiation used by the sensor\n"
        "                        # (sound, IR, etc) [enum]\n"
        "\n"
        "float32 field_of_view   # the size of the arc that the distance reading is\n"
        "                        # valid for [rad]\n"
        "                        # the object causing the range reading may have\n"
        "                        # been anywhere within -field_of_view/2 and\n"
        "                        # field_of_view/2 at the measured range. \n"
        "                        # 0 angle corresponds to the x-axis of the sensor.\n"
        "\n"
        "float32 min_range       # minimum range value [m]\n"
        "float32 max_range       # maximum range value [m]\n"
        "                        # Fixed distance rangers require min_range==max_range\n"
        "\n"
        "float32 range           # range data [m]\n"
        "                        # (Note: values < range_min or > range_max\n"
        "                        # should be discarded)\n"
        "                        # Fixed distance rangers only output -Inf or +Inf.\n"
        "                        # -Inf represents a detection within fixed distance.\n"
        "                        # (Detection too close to the sensor to quantify)\n"
        "                        # +Inf represents no detection within the fixed distance.\n"
        "                        # (Object out of range)"
    ),
    "sensor_msgs/RegionOfInterest": (
        "# This message is used to specify a region of interest within an image.\n"
        "#\n"
        "# When used to specify the ROI setting of the camera when the image was\n"
        "# taken, the height and width fields should either match the height and\n"
        "# width fields for the associated image; or height = width = 0\n"
        "# indicates that the full resolution image was captured.\n"
        "\n"
        "uint32 x_offset  # Leftmost pixel of the ROI\n"
        "                 # (0 if the ROI includes the left edge of the image)\n"
        "uint32 y_offset  # Topmost pixel of the ROI\n"
        "                 # (0 if the ROI includes the top edge of the image)\n"
        "uint32 height    # Height of ROI\n"
        "uint32 width     # Width of ROI\n"
        "\n"
        '# True if a distinct rectified ROI should be calculated from the "raw"\n'
        "# ROI in this message. Typically this should be False if the full image\n"
        "# is captured (ROI not used), and True if a subwindow is captured (ROI\n"
        "# used).\n"
        "bool do_rectify\n"
    ),
    "std_msgs/Float64": ("float64 data"),
    "std_msgs/Float64MultiArray": (
        "# Please look at the MultiArrayLayout message definition for\n"
        "# documentation on all multiarrays.\n"
        "\n"
        "MultiArrayLayout  layout        # specification of data layout\n"
        "float64[]         data          # array of data\n"
        "\n"
    ),
    "std_msgs/Header": (
        "# Standard metadata for higher-level stamped data types.\n"
        "# This is generally used to communicate timestamped data \n"
        "# in a particular coordinate frame.\n"
        "# \n"
        "# sequence ID: consecutively increasing ID \n"
        "uint32 seq\n"
        "#Two-integer timestamp that is expressed as:\n"
        "# * stamp.sec: seconds (stamp_secs) since epoch (in Python the variable is called 'secs')\n"
        "# * stamp.nsec: nanoseconds since stamp_secs (in Python the variable is called 'nsecs')\n"
        "# time-handling sugar is provided by the client library\n"
        "time stamp\n"
        "#Frame this data is associated with\n"
        "string frame_id\n"
    ),
    "std_msgs/MultiArrayDimension": (
        "string label   # label of given dimension\n"
        "uint32 size    # size of given dimension (in type units)\n"
        "uint32 stride  # stride of given dimension"
    ),
    "std_msgs/MultiArrayLayout": (
        "# The multiarray declares a generic multi-dimensional array of a\n"
        "# particular data type.  Dimensions are ordered from outer most\n"
        "# to inner most.\n"
        "\n"
        "MultiArrayDimension[] dim # Array of dimension properties\n"
        "uint32 data_offset        # padding elements at front of data\n"
        "\n"
        "# Accessors should ALWAYS be written in terms of dimension stride\n"
        "# and specified outer-most dimension first.\n"
        "# \n"
        "# multiarray(i,j,k) = data[data_offset + dim_stride[1]*i + dim_stride[2]*j + k]\n"
        "#\n"
        "# A standard, 3-channel 640x480 image with interleaved color channels\n"
        "# would be specified as:\n"
        "#\n"
        '# dim[0].label  = "height"\n'
        "# dim[0].size   = 480\n"
        "# dim[0].stride = 3*640*480 = 921600  (note dim[0] stride is just size of image)\n"
        '# dim[1].label  = "width"\n'
        "# dim[1].size   = 640\n"
        "# dim[1].stride = 3*640 = 1920\n"
        '# dim[2].label  = "channel"\n'
        "# dim[2].size   = 3\n"
        "# dim[2].stride = 3\n"
        "#\n"
        "# multiarray(i,j,k) refers to the ith row, jth column, and kth channel.\n"
    ),
    "std_msgs/String": ("string data\n"),
    "tf2_msgs/TFMessage": ("geometry_msgs/TransformStamped[] transforms\n"),
    **VISUALIZATION_MSG_TEXTS,
    **ROS1_VISION_MSG_TEXTS,
}


_PRIMITIVES = frozenset(
    [
        "bool",
        "byte",
        "char",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "float32",
        "float64",
        "string",
        "time",
        "duration",
    ]
)
_SEPARATOR = "=" * 80 + "\n"


def _depends(name: str) -> list[str]:
    """Message types of ``name``'s fields, in field order (ROS 1 names: ``pkg/Type``)."""
    pkg = name.split("/")[0]
    out: list[str] = []
    for raw in ROS1_MSG_TEXTS[name].splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line or "=" in line:  # blank, comment or constant
            continue
        base = line.split()[0].split("[")[0]
        if base in _PRIMITIVES:
            continue
        dep = "std_msgs/Header" if base == "Header" else base if "/" in base else f"{pkg}/{base}"
        if dep not in out:
            out.append(dep)
    return out


def _all_depends(name: str, seen: list[str]) -> None:
    for dep in _depends(name):
        if dep not in seen:
            seen.append(dep)
            _all_depends(dep, seen)


def ros1_full_text(msgtype: str) -> str | None:
    """The full message definition ROS 1 stores for ``msgtype`` (``pkg/Type`` or
    ``pkg/msg/Type``), or None when its text is not known here."""
    name = msgtype.replace("/msg/", "/")
    if name not in ROS1_MSG_TEXTS:
        return None
    deps: list[str] = []
    _all_depends(name, deps)
    if any(d not in ROS1_MSG_TEXTS for d in deps):
        return None
    sections = [ROS1_MSG_TEXTS[name]] + [f"MSG: {d}\n{ROS1_MSG_TEXTS[d]}" for d in deps]
    return ("\n" + _SEPARATOR).join(sections)
