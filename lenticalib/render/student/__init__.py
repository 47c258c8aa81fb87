"""The student driver: a small network trained per subject that turns a camera frame into the
avatar's controls (the LentiAvatar paper's subject-specific distilled driver).

A MobileNetV3-Small backbone (torchvision; weights from the user's file, never downloaded) with a
two-layer head predicts the normalised control vector from a square crop of the frame; it is
distilled from teacher controls (a tracker's output for the subject's training video) with a
group-weighted smooth-L1 loss.  At run time the prediction is de-normalised with the subject's
statistics and drives the avatar like any other control source.

Modules
    frames        frames from a video file, a folder of images or a camera (OpenCV), checked first
    crop          the crop rule: a fixed box, or one that follows the head; frames to network input
    model         the network: MobileNetV3-Small features and a two-layer head
    student_file  the saved student (``student.pt``): network, layout, crop, statistics, provenance
    distill       ``distill_student``: frames + teacher controls -> a trained student
    predict       ``predict_controls``: a student + frames -> a control file; :class:`StudentPredictor`
    live          the ``student:`` control source of ``play``: a camera or a video, live

Part of the render layer: imports only core and render.  torch and torchvision are imported
only when a student is built or loaded.
"""
