; A kitchen of boxes for the seven manipulation primitives, as a planning expert would write it.
; Objects are described by attribute predicates; geometry enters as facts computed from the
; scene when the problem is written (what the robot reaches from where, what fits where).
; Not expressed, as in the paper: that a liquid is handled only through its container, and
; that nothing is poured or stirred over a shelf.
(define (domain kitchen)
  (:requirements :strips :typing :negative-preconditions :universal-preconditions :conditional-effects)
  (:types obj)
  (:predicates
    (movable ?o - obj) (container ?o - obj) (liquid ?o - obj) (large-surface ?o - obj)
    (multi-surface ?o - obj) (cylinder ?o - obj) (box-shape ?o - obj) (handle ?o - obj)
    (reach-after ?p - obj ?o - obj)
    (receives-inside ?b - obj)
    (room-on ?a - obj ?b - obj)
    (long-enough ?s - obj ?v - obj)
    (near ?o - obj) (hand-empty) (holding ?o - obj) (anchored)
    (on ?a - obj ?b - obj) (in ?a - obj ?b - obj) (above ?a - obj ?b - obj)
    (stirred ?l - obj ?s - obj))

  (:action move_close
    :parameters (?p - obj)
    :precondition (and (not (holding ?p)) (not (anchored)))
    :effect (and (forall (?o - obj) (when (reach-after ?p ?o) (near ?o)))
                 (forall (?o - obj) (when (not (reach-after ?p ?o)) (not (near ?o))))))

  (:action grasp
    :parameters (?o - obj)
    :precondition (and (hand-empty) (near ?o) (movable ?o) (forall (?y - obj) (not (on ?y ?o))))
    :effect (and (holding ?o) (not (hand-empty))
                 (forall (?x - obj) (and (not (on ?o ?x)) (not (in ?o ?x))))))

  (:action place_above
    :parameters (?a - obj ?b - obj)
    :precondition (and (holding ?a) (near ?b) (room-on ?a ?b) (not (anchored)))
    :effect (and (anchored)
                 (when (receives-inside ?b) (in ?a ?b))
                 (when (not (receives-inside ?b)) (on ?a ?b))
                 (forall (?x - obj) (not (above ?a ?x)))))

  (:action release
    :parameters (?a - obj)
    :precondition (and (holding ?a) (anchored))
    :effect (and (hand-empty) (near ?a) (not (holding ?a)) (not (anchored))))

  (:action hold_above
    :parameters (?a - obj ?b - obj)
    :precondition (and (holding ?a) (near ?b) (not (anchored)))
    :effect (and (forall (?x - obj) (not (above ?a ?x))) (above ?a ?b)))

  (:action drop
    :parameters (?a - obj ?b - obj)
    :precondition (and (holding ?a) (above ?a ?b) (room-on ?a ?b))
    :effect (and (hand-empty) (near ?a) (not (holding ?a)) (not (above ?a ?b))
                 (when (receives-inside ?b) (in ?a ?b))
                 (when (not (receives-inside ?b)) (on ?a ?b))))

  (:action follow_traj_circle
    :parameters (?s - obj ?v - obj ?l - obj)
    :precondition (and (holding ?s) (above ?s ?v) (in ?l ?v) (liquid ?l) (long-enough ?s ?v))
    :effect (stirred ?l ?s))

  (:action follow_traj_pour
    :parameters (?a - obj ?b - obj ?l - obj)
    :precondition (and (holding ?a) (above ?a ?b) (in ?l ?a) (liquid ?l) (container ?b))
    :effect (and (in ?l ?b) (not (in ?l ?a)))))
