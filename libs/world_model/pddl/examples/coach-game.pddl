(define (problem coach-game)
  (:domain robocog)
  (:objects
    ball - ball
    field - field
    opponent_goalpost_left opponent_goalpost_right own_goalpost_left own_goalpost_right - goalpost
    coach - human
    center_spot opponent_penalty_mark own_penalty_mark - landmark
    nao_1 nao_2 opponent_1 opponent_2 - robot)
  (:init
    (closest-to-ball nao_2)
    (closest-to-ball opponent_1)
    (fallen opponent_2)
    (in-field ball)
    (in-field nao_1)
    (in-field nao_2)
    (in-field opponent_1)
    (in-field opponent_2))
  (:goal (and (touched ball))))
