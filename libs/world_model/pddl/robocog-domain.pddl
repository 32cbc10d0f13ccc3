; The PDDL domain of robocog's deep representation. The problem files come from
; deep_representation::pddl::export_problem: objects are the DR nodes that predicates talk about
; (names lowercased, characters outside [a-z0-9_-] replaced by '-'), and :init holds every
; predicate that is true in the graph, plus the structural facts has-part and has-camera.
; Geometric predicates are computed by the DR (see deep_representation::predicates); the actions
; below are the symbolic view of the two games (touch the ball; the SPL coach game).
(define (domain robocog)
  (:requirements :strips :typing :negative-preconditions)
  (:types
    physical camera bodypart effector landmark field - object
    item agent - physical
    ball - item
    robot human - agent
    goalpost - landmark)
  (:predicates
    (visible ?t - physical ?c - camera)
    (reachable ?i - item ?p - bodypart)
    (near ?a - object ?i - item)
    (in-field ?t - physical)
    (fallen ?r - robot)
    (closest-to-ball ?r - robot)
    (has-part ?r - robot ?p - bodypart)
    (has-camera ?r - robot ?c - camera)
    (touched ?i - item))

  ; Touch the ball (seed 001): gaze at the item, then reach it with an arm.
  (:action look-at
    :parameters (?r - robot ?c - camera ?i - item)
    :precondition (and (has-camera ?r ?c) (not (fallen ?r)))
    :effect (visible ?i ?c))
  (:action touch
    :parameters (?r - robot ?p - bodypart ?c - camera ?i - item)
    :precondition (and (has-part ?r ?p) (has-camera ?r ?c) (visible ?i ?c)
                       (reachable ?i ?p) (not (fallen ?r)))
    :effect (touched ?i))

  ; Coach game (seed 000): walk to the ball, kick it when closest.
  (:action go-to-ball
    :parameters (?r - robot ?b - ball)
    :precondition (and (in-field ?b) (not (fallen ?r)))
    :effect (near ?r ?b))
  (:action kick
    :parameters (?r - robot ?b - ball)
    :precondition (and (near ?r ?b) (closest-to-ball ?r) (not (fallen ?r)))
    :effect (and (not (near ?r ?b)) (touched ?b))))
