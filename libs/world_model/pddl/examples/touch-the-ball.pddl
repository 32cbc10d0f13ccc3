(define (problem touch-the-ball)
  (:domain robocog)
  (:objects
    ball - ball
    left_arm right_arm - bodypart
    head_rgbd - camera
    player - human
    loki - robot)
  (:init
    (closest-to-ball loki)
    (has-camera loki head_rgbd)
    (has-part loki left_arm)
    (has-part loki right_arm))
  (:goal (and (touched ball))))
